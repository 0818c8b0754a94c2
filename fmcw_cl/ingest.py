"""Raw DAQ dumps and an OSA G(I) table to a capture file (`fmcw-cl import`).

A dump holds the two ADC channels as int16 codes, either interleaved in a headerless
binary file (sample 0 of channel A, sample 0 of channel B, ...) or as a ``.npy`` array
of shape (N, 2) or (2, N). The G(I) table comes as a CSV the way an optical spectrum
analyser exports it: injection current in mA and peak wavelength in nm, one row per
current; header and comment lines are skipped. Wavelengths are taken as vacuum
wavelengths (nu = c / lambda); say `air=True` for an OSA that reports air wavelengths.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np

from .capture import Capture, CaptureWriter, Modulation
from .errors import CaptureError
from .physics import C

CHUNK = 1 << 22        # samples per channel copied at a time
N_AIR = 1.000273       # refractive index of standard air at 1550 nm (Ciddor)


def read_dump(path: str | os.PathLike) -> np.ndarray:
    """The dump as an (N, 2) int16 array (memory-mapped, not loaded).

    Raises
    ------
    CaptureError : not int16, not two channels, or an odd number of values.
    """
    path = Path(path)
    if not path.is_file():
        raise CaptureError(path, "no such file")
    if path.suffix == ".npy":
        try:
            a = np.load(path, mmap_mode="r", allow_pickle=False)
        except ValueError as exc:
            raise CaptureError(path, f"not a readable .npy array ({exc})") from None
        if a.dtype != np.int16:
            raise CaptureError(path, f"the dump holds {a.dtype}, not int16 ADC codes")
        if a.ndim == 2 and a.shape[1] == 2:
            return a
        if a.ndim == 2 and a.shape[0] == 2:
            return a.T
        raise CaptureError(path, f"the dump has shape {a.shape}; expected (N, 2) or (2, N)")
    size = path.stat().st_size
    if size == 0 or size % 4:
        raise CaptureError(path, f"{size} bytes is not a whole number of two-channel int16 samples")
    return np.memmap(path, dtype="<i2", mode="r").reshape(-1, 2)


def read_osa_table(path: str | os.PathLike, air: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """G(I) from an OSA CSV (current mA, wavelength nm) as (current A, frequency Hz),
    sorted by current.

    Raises
    ------
    CaptureError : fewer than 4 numeric rows, or repeated currents.
    """
    path = Path(path)
    if not path.is_file():
        raise CaptureError(path, "no such file")
    text = path.read_text(encoding="utf-8", errors="replace")
    dialect = csv.Sniffer().sniff(text[:2048], delimiters=",;\t ") if text.strip() else csv.excel
    rows = []
    for row in csv.reader(text.splitlines(), dialect):
        cells = [c.strip() for c in row if c.strip()]
        try:
            rows.append((float(cells[0]), float(cells[1])))
        except (IndexError, ValueError):
            continue     # header, units or comment line
    if len(rows) < 4:
        raise CaptureError(path, f"{len(rows)} numeric rows of (current mA, wavelength nm); need at least 4")
    table = np.array(sorted(rows))
    current_a, wavelength_m = table[:, 0] * 1e-3, table[:, 1] * 1e-9
    if np.any(np.diff(current_a) <= 0):
        raise CaptureError(path, "a current appears twice in the G(I) table")
    if np.any(wavelength_m <= 0):
        raise CaptureError(path, "wavelengths must be positive (nm)")
    return current_a, C / (wavelength_m * (N_AIR if air else 1.0))


def import_capture(dump: str | os.PathLike, table: str | os.PathLike, output: str | os.PathLike,
                   sample_rate_hz: float, modulation: Modulation, bits: int = 14,
                   order: str = "beat,sync", refractive_index: float | None = None,
                   air: bool = False, progress=None) -> Path:
    """Write a capture from a dump and an OSA table; the result is validated.

    Parameters
    ----------
    dump : interleaved int16 binary or .npy (see module notes).
    table : OSA CSV, current (mA) and wavelength (nm).
    output : the capture to write (atomically).
    sample_rate_hz : ADC rate (Hz).
    modulation : triangle frequency (Hz) and current range (A).
    bits : effective ADC resolution.
    order : which channel comes first, "beat,sync" or "sync,beat".
    refractive_index : of the medium, written to /optics when given.
    air : the OSA reports air wavelengths.
    progress : callable(done, total, sample_rate_hz), optional.
    """
    if order not in ("beat,sync", "sync,beat"):
        raise ValueError(f"order must be 'beat,sync' or 'sync,beat', not {order!r}")
    data = read_dump(dump)
    current_a, frequency_hz = read_osa_table(table, air)
    lo, hi = modulation.current_min_a, modulation.current_max_a
    if current_a[0] > lo or current_a[-1] < hi:
        raise CaptureError(Path(table), f"the G(I) table ({current_a[0] * 1e3:g}-{current_a[-1] * 1e3:g} mA) "
                                        f"does not cover the modulation range ({lo * 1e3:g}-{hi * 1e3:g} mA)")
    ib, isy = (0, 1) if order == "beat,sync" else (1, 0)
    n = data.shape[0]
    with CaptureWriter(output, n, sample_rate_hz, bits, modulation, current_a, frequency_hz,
                       refractive_index, attrs={"imported_from": str(Path(dump).resolve())}) as w:
        for a in range(0, n, CHUNK):
            block = np.asarray(data[a:a + CHUNK])
            w.write(a, block[:, ib], block[:, isy])
            if progress:
                progress(min(a + CHUNK, n), n, sample_rate_hz)
    try:
        Capture(output).close()          # the contract's checks, naming the new file
    except CaptureError:
        Path(output).unlink(missing_ok=True)
        raise
    return Path(output)
