"""`fmcw-cl import`: DAQ dumps and OSA tables become captures that process like any."""

from __future__ import annotations

import numpy as np
import pytest

from fmcw_cl.capture import Capture, Modulation
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
