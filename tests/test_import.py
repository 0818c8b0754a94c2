"""`fmcw-cl import`: DAQ dumps and OSA tables become captures that process like any."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from fmcw_cl.capture import Capture
from fmcw_cl.capture_format import Modulation
from fmcw_cl.engine import process
from fmcw_cl.errors import CaptureError
from fmcw_cl.ingest import import_capture, read_dump, read_osa_table
from fmcw_cl.physics import C


@pytest.fixture(scope="module")
def raw(static_capture, tmp_path_factory):
    """The static capture taken apart: an interleaved dump, a (2, N) .npy, an OSA CSV."""
    d = tmp_path_factory.mktemp("raw")
    with Capture(static_capture) as cap:
        info = cap.info
        beat, sync = cap.read(0, info.samples)
    np.stack([beat, sync], axis=1).astype("<i2").tofile(d / "dump.bin")
    np.save(d / "dump.npy", np.stack([sync, beat]))
    rows = "\n".join(f"{i * 1e3:.9f}, {C / f * 1e9:.12f}" for i, f in
                     zip(info.tuning_current_a[::-1], info.tuning_frequency_hz[::-1], strict=True))
    header = "# DFB static tuning, OSA export\nCurrent (mA), Wavelength (nm)\n"
    (d / "osa.csv").write_text(header + rows + "\n")
    return d, info, beat, sync


def test_cli_import_binary_processes_like_the_original(raw, static_capture, tmp_path, fmcw):
    d, info, beat, sync = raw
    out = tmp_path / "imported.h5"
    m = info.modulation
    fmcw("import", d / "dump.bin", "--tuning", d / "osa.csv", "-o", out, "--sample-rate", info.sample_rate_hz,
         "--frequency", m.frequency_hz, "--current-min", m.current_min_a, "--current-max", m.current_max_a)
    with Capture(out) as cap:
        b, s = cap.read(0, cap.info.samples)
        np.testing.assert_array_equal(b, beat)
        np.testing.assert_array_equal(s, sync)
        np.testing.assert_allclose(cap.info.tuning_frequency_hz, info.tuning_frequency_hz, rtol=1e-12)
        np.testing.assert_allclose(cap.info.tuning_current_a, info.tuning_current_a, rtol=1e-9)
    a, b = process(static_capture), process(out)
    np.testing.assert_array_equal(a.valid, b.valid)
    np.testing.assert_allclose(a.distance_m, b.distance_m, atol=1e-9)


def test_npy_in_sync_beat_order(raw, tmp_path):
    d, info, beat, sync = raw
    out = import_capture(d / "dump.npy", d / "osa.csv", tmp_path / "n.h5", info.sample_rate_hz,
                         info.modulation, order="sync,beat")
    with Capture(out) as cap:
        np.testing.assert_array_equal(cap.read(0, 1000)[0], beat[:1000])


def test_air_wavelengths_raise_the_frequency(raw):
    d, info, *_ = raw
    _, vac = read_osa_table(d / "osa.csv")
    _, air = read_osa_table(d / "osa.csv", air=True)
    np.testing.assert_allclose(vac / air, 1.000273)


def test_bad_dumps_and_tables(tmp_path, raw, fmcw):
    d, info, *_ = raw
    (tmp_path / "odd.bin").write_bytes(b"\x00" * 6)
    with pytest.raises(CaptureError, match="odd.bin.*whole number"):
        read_dump(tmp_path / "odd.bin")
    np.save(tmp_path / "f.npy", np.zeros((10, 2), np.float32))
    with pytest.raises(CaptureError, match="f.npy.*not int16"):
        read_dump(tmp_path / "f.npy")
    np.save(tmp_path / "three.npy", np.zeros((10, 3), np.int16))
    with pytest.raises(CaptureError, match=r"three.npy.*shape"):
        read_dump(tmp_path / "three.npy")
    (tmp_path / "short.csv").write_text("mA,nm\n200,1550\n300,1550.5\n")
    with pytest.raises(CaptureError, match="short.csv.*need at least 4"):
        read_osa_table(tmp_path / "short.csv")
    (tmp_path / "narrow.csv").write_text("\n".join(f"{i},{1550 + i / 100}" for i in (200, 250, 300, 350)))
    out = tmp_path / "never.h5"
    with pytest.raises(CaptureError, match="narrow.csv.*does not cover"):
        import_capture(d / "dump.bin", tmp_path / "narrow.csv", out, 100e6, Modulation(20e3, 0.16, 0.48))
    assert not out.exists() and not list(tmp_path.glob("*.part"))
    proc = fmcw("import", tmp_path / "odd.bin", "--tuning", d / "osa.csv", "-o", out, check=False)
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1 and "odd.bin" in proc.stderr


def write_tdms(path, channels: dict, interleaved: bool = False, segments: int = 3, props=None):
    """A LabVIEW-style TDMS file by npTDMS's writer: channels group "adc", written in
    `segments` segments; `interleaved` sets the segments' interleaved-data flag and
    interleaves the values (npTDMS's TdmsSegment with that flag)."""
    from nptdms import ChannelObject, TdmsWriter, writer

    class Interleaved(writer.TdmsSegment):
        def write(self, file):
            meta = self.metadata()
            flags = ["kTocMetaData", "kTocRawData", "kTocNewObjList", "kTocInterleavedData"]
            lead = self.leadin(flags, sum(len(v.bytes) for v in meta))
            file.write(b"".join(v.bytes for v in lead + meta))
            data = [o.data for o in self.objects if writer._object_has_data(o)]
            file.write(np.stack(data, axis=1).astype(data[0].dtype.newbyteorder("<")).tobytes())

    original = writer.TdmsSegment
    writer.TdmsSegment = Interleaved if interleaved else original
    try:
        with TdmsWriter(str(path)) as w:
            n = len(next(iter(channels.values())))
            for part in np.array_split(np.arange(n), segments):
                w.write_segment([ChannelObject("adc", name, x[part], properties=props or {})
                                 for name, x in channels.items()])
    finally:
        writer.TdmsSegment = original
    return path


@pytest.mark.parametrize("interleaved", [False, True])
@pytest.mark.parametrize("scaled", [False, True])
def test_tdms_recording_imports_and_converts_like_the_original(raw, static_capture, tmp_path, fmcw,
                                                               interleaved, scaled):
    """Raw int16 codes or scaled volts (+-2 V full scale), contiguous or interleaved,
    with a channel that is neither: named channels, the rate from wf_increment."""
    d, info, beat, sync = raw
    full_scale = 2.0
    to_unit = (lambda x: x.astype(np.float64) * full_scale / 8192) if scaled else (lambda x: x)
    rec = write_tdms(tmp_path / "run.tdms",
                     {"temperature": to_unit(np.zeros(beat.size, np.int16)),
                      "sync": to_unit(sync), "beat": to_unit(beat)},
                     interleaved=interleaved, props={"wf_increment": 1 / info.sample_rate_hz})
    out = tmp_path / "run.h5"
    m = info.modulation
    args = ["import", rec, "--tuning", d / "osa.csv", "-o", out, "--beat-channel", "adc/beat",
            "--sync-channel", "adc/sync", "--frequency", m.frequency_hz, "--current-min", m.current_min_a,
            "--current-max", m.current_max_a, "-q"]
    fmcw(*args, *(["--full-scale-volts", full_scale] if scaled else []))
    with Capture(out) as cap:
        assert cap.info.sample_rate_hz == pytest.approx(info.sample_rate_hz)
        b, s = cap.read(0, cap.info.samples)
    np.testing.assert_array_equal(b, beat)
    np.testing.assert_array_equal(s, sync)
    a, t = process(static_capture), process(out)
    np.testing.assert_array_equal(a.valid, t.valid)
    np.testing.assert_allclose(a.distance_m, t.distance_m, atol=1e-9)


def test_tdms_refusals(raw, tmp_path, fmcw):
    d, info, beat, sync = raw
    m = info.modulation
    common = ["--tuning", d / "osa.csv", "-o", tmp_path / "x.h5", "--frequency", m.frequency_hz]
    volts = write_tdms(tmp_path / "v.tdms", {"beat": beat / 4096.0, "sync": sync / 4096.0}, segments=1,
                       props={"wf_increment": 1e-8})
    no_rate = write_tdms(tmp_path / "r.tdms", {"beat": beat, "sync": sync}, segments=1)
    cases = ((volts, [], "--full-scale-volts"), (volts, ["--beat-channel", "adc/nope"], "adc/beat"),
             (no_rate, [], "--sample-rate"))
    for rec, extra, word in cases:
        proc = fmcw("import", rec, *common, *extra, check=False)
        assert proc.returncode == 1 and word in proc.stderr and proc.stderr.count("\n") == 1, proc.stderr
    assert not (tmp_path / "x.h5").exists()


REAL = Path(__file__).parent / "data" / "tdms"       # written by LabVIEW and NI-DAQmx (README there)


@pytest.fixture()
def osa(tmp_path):
    """A G(I) table over 100-500 mA (any laser: these files hold no FMCW signal)."""
    rows = "\n".join(f"{i}, {C / (193e12 + (i - 100) * 0.4e9) * 1e9:.9f}" for i in range(100, 520, 20))
    (tmp_path / "osa.csv").write_text("mA, nm\n" + rows + "\n")
    return tmp_path / "osa.csv"


def test_daqmx_raw_data_is_read_raw(tmp_path, osa, fmcw):
    """A DAQmx log (raw int16 of a 16-bit device, +-10 V, interleaved, scale properties,
    3 segments): the capture's codes are the ADC's, bit for bit, without
    --full-scale-volts, and its resolution is theirs (16 bits), without --bits: a
    default of 14 clipped half of a PCI-6133's log."""
    from nptdms import TdmsFile

    out = tmp_path / "daqmx.h5"
    proc = fmcw("import", REAL / "npTDMS_raw1.tdms", "--tuning", osa, "-o", out, "--sample-rate", "100e6",
                "--frequency", "1e6", "--sync-channel", "Layer Data/Fifth Chan", "-q")
    assert "clipped" not in proc.stderr
    with TdmsFile.open(REAL / "npTDMS_raw1.tdms") as f:
        beat = f["Layer Data"]["First  Channel"].read_data(scaled=False)
        sync = f["Layer Data"]["Fifth Chan"].read_data(scaled=False)
        volts = f["Layer Data"]["First  Channel"].read_data()
    (beat,), (sync,) = beat.values(), sync.values()
    assert beat.dtype == np.int16 and volts.dtype == np.float64      # npTDMS scales it by default
    with Capture(out) as cap:
        b, s = cap.read(0, cap.info.samples)
    np.testing.assert_array_equal(b, beat)
    np.testing.assert_array_equal(s, sync)
    with Capture(out) as cap:
        assert cap.info.bits == 16


@pytest.mark.parametrize("peak,bits", [(8191, 14), (8192, 16), (-8193, 16), (32767, 16)])
def test_a_dumps_resolution_is_its_codes_unless_told(tmp_path, static_capture, peak, bits):
    """Without --bits a dump is 14 bits where its codes fit, else 16, none clipped;
    told 14, codes beyond are clipped and counted."""
    with Capture(static_capture) as cap:
        b, s = cap.read(0, 20_000)
    b = b.copy()
    b[100] = peak
    dump = tmp_path / "d.npy"
    np.save(dump, np.stack([b, s], axis=1))
    rows = "\n".join(f"{i}, {C / (193e12 + (i - 100) * 0.4e9) * 1e9:.9f}" for i in range(100, 520, 20))
    (tmp_path / "osa.csv").write_text(rows + "\n")
    warned = []
    out = import_capture(dump, tmp_path / "osa.csv", tmp_path / "d.h5", 100e6, Modulation(20e3, 0.16, 0.48),
                         warn=warned.append)
    with Capture(out) as cap:
        assert cap.info.bits == bits and cap.read(100, 101)[0][0] == peak
    assert warned == []
    told = import_capture(dump, tmp_path / "osa.csv", tmp_path / "t.h5", 100e6, Modulation(20e3, 0.16, 0.48),
                          bits=14, warn=warned.append)
    with Capture(told) as cap:
        assert cap.info.bits == 14 and cap.read(100, 101)[0][0] == np.clip(peak, -8192, 8191)
    assert len(warned) == (bits == 16) and (bits == 14 or "1 samples" in warned[0])


def test_labview_group_names_with_slashes(tmp_path, osa, fmcw):
    group = "07/09/2012 06:58:23 PM - Digital Input - All Data"
    name = f"{group}/Dev1_port3_line7 - line 0"
    out = tmp_path / "digital.h5"
    fmcw("import", REAL / "npTDMS_Digital_Input.tdms", "--tuning", osa, "-o", out, "--beat-channel", name,
         "--sync-channel", name, "--sample-rate", "100e6", "--frequency", "1e6", "-q")
    with Capture(out) as cap:
        assert cap.info.samples == 20000
    wrong = fmcw("import", REAL / "npTDMS_Digital_Input.tdms", "--tuning", osa, "-o", tmp_path / "x.h5",
                 "--beat-channel", f"{group}/nope", check=False)
    assert wrong.returncode == 1 and wrong.stderr.count("\n") == 1
    assert f"no channel '{group}/nope'" in wrong.stderr and repr(name) in wrong.stderr


def test_values_beyond_full_scale_are_clipped_and_counted(tmp_path, osa, fmcw):
    """LabVIEW's float64 example (big-endian, values up to about 3) with a 1 V range:
    volts say nothing of the ADC's resolution: 14 bits unless --bits says otherwise."""
    out = tmp_path / "volts.h5"
    proc = fmcw("import", REAL / "npTDMS_big_endian.tdms", "--tuning", osa, "-o", out,
                "--full-scale-volts", "1", "--frequency", "10", "-q")
    warned = [line for line in proc.stderr.splitlines() if line.startswith("warning:")]
    assert len(warned) == 2 and "of the beat channel lie beyond the 14-bit full scale" in warned[0]
    share = float(re.search(r"\(([\d.]+) %\)", warned[0]).group(1))
    with Capture(out) as cap:
        b, _ = cap.read(0, cap.info.samples)
        assert cap.info.sample_rate_hz == pytest.approx(1e3)
    at_rail = np.mean((b == 8191) | (b == -8192))
    assert at_rail == pytest.approx(share / 100, abs=1e-3) and share > 1


def test_what_is_not_a_number_is_refused_by_what_it_is(tmp_path, osa, fmcw):
    from nptdms import ChannelObject, TdmsWriter

    path = tmp_path / "text.tdms"
    with TdmsWriter(str(path)) as w:
        stamps = np.array(["2024-01-01T00:00"] * 300, "datetime64[us]")
        w.write_segment([ChannelObject("log", "note", np.array(["a", "b", "c"] * 100)),
                         ChannelObject("log", "when", stamps)])
    for channel, what in (("log/note", "holds text"), ("log/when", "holds timestamps")):
        proc = fmcw("import", path, "--tuning", osa, "-o", tmp_path / "x.h5", "--beat-channel", channel,
                    "--sync-channel", channel, "--sample-rate", "100e6", "--full-scale-volts", "1",
                    check=False)
        assert proc.returncode == 1 and proc.stderr.count("\n") == 1 and what in proc.stderr, proc.stderr
        assert channel in proc.stderr and "Traceback" not in proc.stderr


def test_settings_are_checked_before_the_samples_are_read(tmp_path, osa, fmcw, monkeypatch):
    """A rate or a modulation the capture layout does not allow is refused naming the
    input and the flag, and nothing is read or written."""
    from fmcw_cl import ingest

    cases = ((["--sample-rate", "1"], "--sample-rate"), (["--frequency", "5e7"], "--frequency"),
             (["--current-min", "0.5"], "--current-min"), (["--bits", "20"], "--bits"))
    for extra, flag in cases:
        proc = fmcw("import", REAL / "npTDMS_raw1.tdms", "--tuning", osa, "-o", tmp_path / "x.h5",
                    "--sample-rate", "100e6", *extra, check=False)
        assert proc.returncode == 1 and proc.stderr.count("\n") == 1, proc.stderr
        assert "npTDMS_raw1.tdms" in proc.stderr and flag in proc.stderr, proc.stderr
    assert not list(tmp_path.glob("x.h5*"))
    read = []
    monkeypatch.setattr(ingest.TdmsChannels, "__getitem__", lambda self, rows: read.append(rows))
    with pytest.raises(CaptureError, match="sample rate of 1 Hz"):
        import_capture(REAL / "npTDMS_raw1.tdms", osa, tmp_path / "x.h5", 1.0, Modulation(20e3, 0.16, 0.48))
    assert read == []
