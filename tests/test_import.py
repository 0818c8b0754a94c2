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
