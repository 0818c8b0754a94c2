"""Raw DAQ dumps or LabVIEW TDMS recordings, and an OSA G(I) table, to a capture file
(`fmcw-cl import`).

A dump holds the two ADC channels as int16 codes, either interleaved in a headerless
binary file (sample 0 of channel A, sample 0 of channel B, ...) or as a ``.npy`` array
of shape (N, 2) or (2, N). The G(I) table comes as a CSV the way an optical spectrum
analyser exports it: injection current in mA and peak wavelength in nm, one row per
current; header and comment lines are skipped. Wavelengths are taken as vacuum
wavelengths (nu = c / lambda); say `air=True` for an OSA that reports air wavelengths.

A TDMS recording (LabVIEW's own format, read by npTDMS) names its channels GROUP/CHANNEL,
matched whole against the file's names (LabVIEW's group names hold '/'); by default the
first two channels of the first group are the beat and the sync. Its sample rate is the
waveform property `wf_increment` (1 / rate). Integer channels hold ADC codes; DAQmx raw
data (which npTDMS reports through its scale, as float64) is read raw, through its one
raw scaler, so the codes are the ADC's bit for bit (int16: 16 bits, a DAQmx scale of
10 V / 32768 a code); float channels hold scaled volts, turned back into codes with the
ADC's input range (`full_scale_volts`: +-V is +-2^(bits-1), 14 bits unless told). A
dump's resolution, unless told, is 14 bits, or 16 where its codes go beyond 14. Text,
timestamps and other channels that are not numbers are refused by what they are. It is
read in ranges (npTDMS's streaming mode, either data layout), so a recording larger than
memory imports in bounded memory.

The settings (rate, bits, modulation) and the channels are checked before a sample is
read; samples beyond the ADC's full scale are clipped and counted in a warning.
"""

from __future__ import annotations

import csv
import os
import warnings
from pathlib import Path

import numpy as np

from .capture import Capture
from .capture_format import LIMITS, Modulation
from .capture_writer import CaptureWriter
from .errors import CaptureError
from .physics import C

CHUNK = 1 << 22        # samples per channel copied at a time
FILE_BITS = 16         # a TDMS recording's raw codes: int16's width (DAQmx raw data)
DUMP_BITS = (14, 16)   # a dump's codes, without --bits: the narrowest of these that holds them
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


class TdmsChannels:
    """The beat and sync channels of a TDMS recording as an (N, 2) source of codes:
    `shape`, `data[a:b]` (int32, read from the file on demand), `sample_rate_hz`."""

    def __init__(self, path: str | os.PathLike, beat: str | None = None, sync: str | None = None,
                 full_scale_volts: float | None = None, bits: int | None = None) -> None:
        from .tables import optional

        nptdms = optional("nptdms", "TDMS import")
        self.path = Path(path)
        if not self.path.is_file():
            raise CaptureError(self.path, "no such file")
        try:
            self.file = nptdms.TdmsFile.open(self.path)
        except Exception as exc:  # noqa: BLE001 - npTDMS raises several kinds for a bad file
            raise CaptureError(self.path, f"not a readable TDMS file ({exc})") from None
        try:
            self.channels = [self._channel(name, k) for k, name in enumerate((beat, sync))]
            lengths = {len(c) for c in self.channels}
            if len(lengths) != 1:
                raise CaptureError(self.path, "the beat and sync channels differ in length "
                                              f"({sorted(lengths)})")
            self.shape = (lengths.pop(), 2)
            self.raw = [self._is_raw(c, nptdms) for c in self.channels]
            # codes of a raw channel span its integers' width (DAQmx: int16 over its scale's
            # range, 10 V / 32768 a code); volts say nothing of the ADC's (the contract's 14)
            self.bits = bits or (FILE_BITS if all(self.raw) else DUMP_BITS[0])
            self.scale = [None if raw else self._codes_per_unit(c, full_scale_volts, self.bits)
                          for c, raw in zip(self.channels, self.raw, strict=True)]
            rates = {1.0 / float(c.properties["wf_increment"]) for c in self.channels
                     if float(c.properties.get("wf_increment", 0) or 0) > 0}
            if len(rates) > 1:
                raise CaptureError(self.path, f"the channels' wf_increment disagree ({sorted(rates)} Hz)")
            self.sample_rate_hz = rates.pop() if rates else None
        except CaptureError:
            self.file.close()
            raise

    def _name(self, channel) -> str:
        return f"{channel.group_name}/{channel.name}"

    def _channel(self, name: str | None, k: int):
        groups = self.file.groups()
        if name is None:
            chans = groups[0].channels() if groups else []
            if len(chans) < 2:
                raise CaptureError(self.path, "the first group holds fewer than two channels: "
                                              "name them (--beat-channel, --sync-channel GROUP/CHANNEL)")
            return chans[k]
        # group and channel names may hold '/' (LabVIEW's "07/09/2012 ... - All Data"):
        # match the whole name against the file's own
        found = [c for g in groups for c in g.channels() if f"{g.name}/{c.name}" == name]
        if len(found) != 1:
            have = "; ".join(repr(f"{g.name}/{c.name}") for g in groups for c in g.channels())
            what = "no channel" if not found else "several channels named"
            raise CaptureError(self.path, f"{what} {name!r} (it holds {have or 'no channels'})")
        return found[0]

    def _is_raw(self, channel, nptdms) -> bool:
        """Whether the channel holds ADC codes: integers, or DAQmx raw data (read through
        its one raw scaler, never its scale); refuses what is not a number."""
        where = self._name(channel)
        if channel.data_type is nptdms.types.DaqMxRawData:
            kinds = [np.dtype(getattr(x, "nptype", x)) for x in channel.scaler_data_types.values()]
            if len(kinds) != 1 or kinds[0].kind not in "iu":
                raise CaptureError(self.path, f"{where} is DAQmx raw data of {len(kinds)} raw scalers "
                                              f"({', '.join(map(str, kinds))}): not one channel of integer "
                                              "ADC codes")
            return True
        dtype = np.dtype(channel.dtype)
        if dtype.kind in "iu":
            return True
        if dtype.kind != "f":
            what = {"O": "text", "U": "text", "S": "bytes", "M": "timestamps", "m": "time spans",
                    "b": "booleans", "c": "complex values"}.get(dtype.kind, str(dtype))
            raise CaptureError(self.path, f"{where} holds {what}, not ADC samples")
        return False

    def _codes_per_unit(self, channel, full_scale_volts: float | None, bits: int) -> float:
        if not full_scale_volts:
            raise CaptureError(self.path, f"{self._name(channel)} holds scaled values "
                                          f"({channel.dtype}): give the ADC's input range "
                                          "(--full-scale-volts)")
        return 2 ** (bits - 1) / full_scale_volts

    def __getitem__(self, rows: slice) -> np.ndarray:
        a, b, _ = rows.indices(self.shape[0])
        out = np.empty((max(0, b - a), 2), np.int32)
        for k, (c, raw, scale) in enumerate(zip(self.channels, self.raw, self.scale, strict=True)):
            x = c.read_data(a, b - a, scaled=not raw)
            if isinstance(x, dict):                     # DAQmx raw data: {scaler: codes}
                (x,) = x.values()
            x = np.asarray(x)
            out[:, k] = x if scale is None else np.clip(np.rint(x * scale), -(2 ** 31), 2 ** 31 - 1)
        return out

    def close(self) -> None:
        self.file.close()


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
                   sample_rate_hz: float | None, modulation: Modulation, bits: int | None = None,
                   order: str = "beat,sync", refractive_index: float | None = None,
                   air: bool = False, progress=None, beat_channel: str | None = None,
                   sync_channel: str | None = None, full_scale_volts: float | None = None,
                   warn=None) -> Path:
    """Write a capture from a dump or a TDMS recording and an OSA table; the result is
    validated.

    Parameters
    ----------
    dump : interleaved int16 binary, .npy, or .tdms (see module notes).
    table : OSA CSV, current (mA) and wavelength (nm).
    output : the capture to write (atomically).
    sample_rate_hz : ADC rate (Hz); None: a TDMS recording's wf_increment.
    modulation : triangle frequency (Hz) and current range (A).
    bits : effective ADC resolution; None: from the file (a TDMS recording's raw codes:
        16, int16's width; its volts: 14; a dump: 14, or 16 where its codes go beyond).
    order : which channel comes first, "beat,sync" or "sync,beat".
    refractive_index : of the medium, written to /optics when given.
    air : the OSA reports air wavelengths.
    progress : callable(done, total, sample_rate_hz), optional.
    beat_channel, sync_channel : TDMS only: GROUP/CHANNEL (default: the first group's
        first two channels; `order` does not apply).
    full_scale_volts : TDMS float channels: the ADC's input range (+-V).
    warn : callable(message) for samples beyond the ADC's full scale, which are clipped
        (default: warnings.warn).

    Raises
    ------
    CaptureError : naming the input and the problem, before any sample is read where
        the settings or the channels are wrong.
    """
    if order not in ("beat,sync", "sync,beat"):
        raise ValueError(f"order must be 'beat,sync' or 'sync,beat', not {order!r}")
    tdms = Path(dump).suffix.lower() == ".tdms"
    data = TdmsChannels(dump, beat_channel, sync_channel, full_scale_volts, bits) if tdms else read_dump(dump)
    bits = data.bits if tdms else bits
    try:
        return _write_capture(data, dump, table, output, sample_rate_hz, modulation, bits,
                              "beat,sync" if tdms else order, refractive_index, air, progress,
                              warn or (lambda m: warnings.warn(m, stacklevel=3)))
    finally:
        if tdms:
            data.close()


def check_settings(dump, samples: int, sample_rate_hz: float | None, modulation: Modulation,
                   bits: int | None) -> None:
    """Refuse, before any sample is read, settings the capture layout does not allow
    (capture_format.validate's limits), naming the input and the setting."""
    where = Path(dump)
    fs = sample_rate_hz
    if not fs:
        raise CaptureError(where, "no sample rate: give --sample-rate (the recording has no wf_increment)")
    lo, hi = LIMITS["sample_rate_hz"]
    if not lo <= fs <= hi:
        raise CaptureError(where, f"a sample rate of {fs:g} Hz is outside [{lo:g}, {hi:g}] Hz "
                                  "(--sample-rate)")
    lo, hi = LIMITS["bits"]
    if bits is not None and not lo <= bits <= hi:
        raise CaptureError(where, f"{bits} bits is outside [{lo}, {hi}] (--bits)")
    f = modulation.frequency_hz
    if not LIMITS["frequency_hz"][0] <= f <= fs / 20:
        raise CaptureError(where, f"a modulation of {f:g} Hz is outside [{LIMITS['frequency_hz'][0]:g}, "
                                  f"{fs / 20:g}] Hz at {fs:g} Hz sampling (--frequency)")
    lo, hi = LIMITS["current_a"]
    imin, imax = modulation.current_min_a, modulation.current_max_a
    if not (lo <= imin < imax <= hi):
        raise CaptureError(where, f"the current range {imin:g}-{imax:g} A must rise within "
                                  f"[{lo:g}, {hi:g}] A (--current-min, --current-max)")
    if samples < 2 * fs / f:
        raise CaptureError(where, f"{samples} samples are fewer than two modulation periods "
                                  f"({2 * fs / f:.0f} samples at {f:g} Hz, {fs:g} Hz sampling)")


def _write_capture(data, dump, table, output, sample_rate_hz, modulation, bits, order, refractive_index,
                   air, progress, warn) -> Path:
    sample_rate_hz = sample_rate_hz or getattr(data, "sample_rate_hz", None)
    n = data.shape[0]
    check_settings(dump, n, sample_rate_hz, modulation, bits)
    current_a, frequency_hz = read_osa_table(table, air)
    lo, hi = modulation.current_min_a, modulation.current_max_a
    if current_a[0] > lo or current_a[-1] < hi:
        raise CaptureError(Path(table), f"the G(I) table ({current_a[0] * 1e3:g}-{current_a[-1] * 1e3:g} mA) "
                                        f"does not cover the modulation range ({lo * 1e3:g}-{hi * 1e3:g} mA)")
    ib, isy = (0, 1) if order == "beat,sync" else (1, 0)
    code_lo, code_hi = -(2 ** ((bits or 16) - 1)), 2 ** ((bits or 16) - 1) - 1
    clipped = np.zeros(2, np.int64)
    widest = 0                                           # the largest |code| seen
    with CaptureWriter(output, n, sample_rate_hz, bits or DUMP_BITS[0], modulation, current_a, frequency_hz,
                       refractive_index, attrs={"imported_from": str(Path(dump).resolve())}) as w:
        for a in range(0, n, CHUNK):
            block = np.asarray(data[a:a + CHUNK])
            clipped += np.sum((block < code_lo) | (block > code_hi), axis=0)
            block = np.clip(block, code_lo, code_hi).astype(np.int16)
            if block.size:
                widest = max(widest, int(block.max()), -int(block.min()) - 1)
            w.write(a, block[:, ib], block[:, isy])
            if progress:
                progress(min(a + CHUNK, n), n, sample_rate_hz)
        if bits is None:                                 # a dump's codes say how wide they are
            bits = next(b for b in DUMP_BITS if widest < 2 ** (b - 1) or b == DUMP_BITS[-1])
            w.set_bits(bits)
    try:
        Capture(output).close()          # the contract's checks, naming the new file
    except CaptureError:
        Path(output).unlink(missing_ok=True)
        raise
    for name, k in (("beat", ib), ("sync", isy)):
        if clipped[k]:
            warn(f"{dump}: {clipped[k]} samples ({100 * clipped[k] / n:.2f} %) of the {name} channel lie "
                 f"beyond the {bits}-bit full scale and were clipped to [{code_lo}, {code_hi}] "
                 "(--full-scale-volts, --bits)")
    return Path(output)
