"""Capture files (contract section 1): open, validate, read in chunks, write.

A capture holds two int16 ADC channels (beat, sync) that may be several GB long, so
reading is always by sample range; nothing here loads a whole channel.
"""

from __future__ import annotations

import contextlib
import math
import mmap
import os
import re
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from . import pool
from .atomic import atomic_path
from .errors import CaptureError
from .extents import ITEM, Extents, read_all, unmap_later

FORMAT = "capture"
FORMAT_VERSION = 1


@dataclass(frozen=True)
class Modulation:
    """Injection-current modulation: a symmetric triangle between two currents."""

    frequency_hz: float
    current_min_a: float
    current_max_a: float
    waveform: str = "triangle"

    @property
    def period_s(self) -> float:
        return 1.0 / self.frequency_hz


@dataclass(frozen=True)
class CaptureInfo:
    """Everything about a capture except its samples."""

    path: Path
    samples: int
    sample_rate_hz: float
    bits: int
    modulation: Modulation
    tuning_current_a: np.ndarray
    tuning_frequency_hz: np.ndarray
    refractive_index: float = 1.0
    has_truth: bool = False

    @property
    def duration_s(self) -> float:
        return self.samples / self.sample_rate_hz

    @property
    def samples_per_period(self) -> float:
        """Nominal modulation period in samples (not necessarily an integer)."""
        return self.sample_rate_hz / self.modulation.frequency_hz

    @property
    def periods(self) -> float:
        return self.samples / self.samples_per_period

    def core_samples(self, periods: int) -> int:
        """Samples in the core of a chunk of `periods` modulation periods (chunks start at
        multiples of this)."""
        return max(1, round(periods * self.samples_per_period))

    @property
    def full_scale(self) -> int:
        """Largest positive ADC code, 2**(bits-1) - 1."""
        return 2 ** (self.bits - 1) - 1


@dataclass(frozen=True)
class Chunk:
    """Samples [start, stop) of both channels; `core` is the range this chunk owns.

    The margins around the core let a stage look past the core's ends (filters,
    interpolation, a half-sweep that starts in the core and ends after it).
    """

    start: int
    beat: np.ndarray
    sync: np.ndarray
    core_start: int
    core_stop: int

    @property
    def stop(self) -> int:
        return self.start + self.beat.size


@dataclass(frozen=True)
class Truth:
    """The true trajectory written by simulators (SI units)."""

    time_s: np.ndarray
    distance_m: np.ndarray
    velocity_mps: np.ndarray
    acceleration_mps2: np.ndarray
    visible: np.ndarray | None = None   # where the echo can be seen (None: always)
    kind: str = "moving"                # "moving", or "fixed" for a static reflector


TRUTH_FIELDS = ("time_s", "distance_m", "velocity_mps", "acceleration_mps2")


def _read_truth(g: h5py.Group) -> Truth:
    visible = np.asarray(g["visible"][()], bool) if "visible" in g else None
    return Truth(*(np.asarray(g[k][()], dtype=np.float64) for k in TRUTH_FIELDS), visible,
                 str(g.attrs.get("kind", "moving")))


def _attr(obj: h5py.HLObject, name: str, path: Path, where: str):
    if name not in obj.attrs:
        raise CaptureError(path, f"missing attribute {where} {name!r}")
    value = obj.attrs[name]
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(()).item()
    return value


def _number(obj, name: str, path: Path, where: str, lo: float, hi: float) -> float:
    value = _attr(obj, name, path, where)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise CaptureError(path, f"attribute {where} {name!r} is not a number: {value!r}") from None
    if not (math.isfinite(x) and lo <= x <= hi):
        raise CaptureError(path, f"attribute {where} {name!r} = {x:g} is outside [{lo:g}, {hi:g}]")
    return x


def _dataset(f: h5py.File, name: str, path: Path) -> h5py.Dataset:
    obj = f.get(name)
    if not isinstance(obj, h5py.Dataset):
        raise CaptureError(path, f"missing dataset {name}")
    return obj


# the contract's ranges of the ADC's and the modulation's attributes (validate; the
# import checks them before it reads a sample); the modulation's upper bound is fs / 20
LIMITS = {"sample_rate_hz": (1e3, 1e12), "bits": (2, 16), "frequency_hz": (1e-3, None),
          "current_a": (0.0, 100.0)}


def validate(f: h5py.File, path: Path) -> CaptureInfo:
    """Check an open HDF5 file against the capture contract and describe it.

    Raises
    ------
    CaptureError
        naming the file and the first problem found.
    """
    kind = f.attrs.get("fmcw_format")
    if isinstance(kind, bytes):
        kind = kind.decode()
    if kind != FORMAT:
        got = "missing" if kind is None else repr(kind)
        raise CaptureError(path, f"not a capture file (attribute fmcw_format is {got})")
    version = _attr(f, "format_version", path, "/")
    if int(version) != FORMAT_VERSION:
        raise CaptureError(path, f"unsupported capture format_version {version}")

    beat = _dataset(f, "adc/beat", path)
    sync = _dataset(f, "adc/sync", path)
    for ds in (beat, sync):
        if ds.ndim != 1 or ds.dtype.kind not in "iu":
            raise CaptureError(path, f"{ds.name} must be a 1-D integer array, got {ds.dtype}{ds.shape}")
    if beat.shape != sync.shape:
        raise CaptureError(path, f"/adc/beat has {beat.shape[0]} samples but /adc/sync has {sync.shape[0]}")
    adc = f["adc"]
    fs = _number(adc, "sample_rate_hz", path, "/adc", *LIMITS["sample_rate_hz"])
    bits = int(_number(adc, "bits", path, "/adc", *LIMITS["bits"]))

    mod = f.get("modulation")
    if mod is None:
        raise CaptureError(path, "missing group /modulation")
    waveform = str(_attr(mod, "waveform", path, "/modulation"))
    if waveform != "triangle":
        raise CaptureError(path, f"modulation waveform {waveform!r} is not supported (only 'triangle')")
    fmod = _number(mod, "frequency_hz", path, "/modulation", LIMITS["frequency_hz"][0], fs / 20)
    imin = _number(mod, "current_min_a", path, "/modulation", *LIMITS["current_a"])
    imax = _number(mod, "current_max_a", path, "/modulation", *LIMITS["current_a"])
    if not imin < imax:
        raise CaptureError(path, f"current_min_a ({imin:g} A) is not below current_max_a ({imax:g} A)")

    cur = np.asarray(_dataset(f, "laser/tuning_current_a", path)[()], dtype=np.float64)
    freq = np.asarray(_dataset(f, "laser/tuning_frequency_hz", path)[()], dtype=np.float64)
    if cur.ndim != 1 or cur.shape != freq.shape or cur.size < 4:
        raise CaptureError(path, "the G(I) table needs two 1-D arrays of the same length, at least 4 points")
    if not (np.all(np.isfinite(cur)) and np.all(np.isfinite(freq))):
        raise CaptureError(path, "the G(I) table holds NaN or infinite values")
    if np.any(np.diff(cur) <= 0):
        raise CaptureError(path, "the G(I) table currents are not strictly increasing")
    if cur[0] > imin or cur[-1] < imax:
        raise CaptureError(
            path,
            f"the G(I) table ({cur[0] * 1e3:g}-{cur[-1] * 1e3:g} mA) does not cover the "
            f"modulation range ({imin * 1e3:g}-{imax * 1e3:g} mA)",
        )
    if np.any(freq <= 0):
        raise CaptureError(path, "the G(I) table frequencies must be absolute optical frequencies (Hz > 0)")

    n = 1.0
    optics = f.get("optics")
    if optics is not None and "refractive_index" in optics.attrs:
        n = _number(optics, "refractive_index", path, "/optics", 1.0, 5.0)

    info = CaptureInfo(
        path=path,
        samples=int(beat.shape[0]),
        sample_rate_hz=fs,
        bits=bits,
        modulation=Modulation(fmod, imin, imax, waveform),
        tuning_current_a=cur,
        tuning_frequency_hz=freq,
        refractive_index=n,
        has_truth="truth/distance_m" in f,
    )
    if info.samples < 2 * info.samples_per_period:
        raise CaptureError(
            path, f"capture is too short: {info.samples} samples, fewer than two modulation periods"
        )
    return info


def _open_problem(message: str) -> str:
    """h5py's open error in a user's words."""
    m = re.search(r"truncated file: eof = (\d+).*stored_eof = (\d+)", message)
    if m:
        return (f"truncated HDF5 file ({int(m.group(1))} of {int(m.group(2))} bytes: an interrupted "
                "copy or write?)")
    return f"not a readable HDF5 file ({message.split('(')[0].strip() or 'unreadable'})"


class Capture:
    """An open capture file. Use as a context manager; read by sample range.

    Parameters
    ----------
    path : the capture file.
    in_place : bool
        Give the chunk reader's chunks (`chunks` with slots) as read-only views of the
        file's pages where both channels lie raw in one run of the file each (a
        contiguous dataset, as `CaptureWriter` stores them uncompressed): no copy, for a
        processor on the CPU (`ChunkProcessor.reads_in_place`). Other layouts are read.

    Examples
    --------
    >>> with Capture("run.h5") as cap:                      # doctest: +SKIP
    ...     for chunk in cap.chunks(periods=4096, margin=6000):
    ...         ...
    """

    def __init__(self, path: str | os.PathLike, in_place: bool = False) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise CaptureError(self.path, "no such file")
        try:
            self._file = h5py.File(self.path, "r")
        except OSError as exc:
            raise CaptureError(self.path, _open_problem(str(exc))) from None
        try:
            self.info = validate(self._file, self.path)
        except CaptureError:
            self._file.close()
            raise
        except (KeyError, OSError, TypeError, ValueError) as exc:
            self._file.close()
            raise CaptureError(self.path, f"damaged capture ({exc})") from None
        self._beat = self._file["adc/beat"]
        self._sync = self._file["adc/sync"]
        # channels stored raw are read straight from the file (fmcw_cl.extents)
        self._extents = [Extents.of(self._beat), Extents.of(self._sync)]
        self._fd = os.open(self.path, os.O_RDONLY) if any(self._extents) else None
        self._mmap: mmap.mmap | None = None
        self._map_offsets: list[int] = []
        self._mapped = self._map() if in_place else None
        self._slots: list[tuple[np.ndarray, np.ndarray]] = []
        self._slots_lock = threading.Lock()     # the chunk reader's thread takes slots too
        self.held: tuple | None = None          # (key, value) of what the held slot holds now
                                                # (refine.stretches: read once, converted often)

    def __enter__(self) -> Capture:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _map(self) -> tuple[np.ndarray, ...] | None:
        """Both channels as read-only arrays over the file mapped in memory, where each
        lies raw in one run of the file (`Extents.file_offset`), else None. Views of them
        are the page cache itself: a chunk that a CPU's processor reads in place costs no
        copy (a 2 s capture's two channels: 800 MB, 110-150 ms of CPU read here)."""
        offsets = [None if e is None else e.file_offset() for e in self._extents]
        if self._fd is None or None in offsets:
            return None
        try:
            mapped = mmap.mmap(self._fd, 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError):
            return None
        if max(offsets) + ITEM * self.info.samples > len(mapped):
            return None                  # a truncated file: the reads name it
        self._map_offsets = offsets
        self._mmap = mapped     # closed with the capture where no chunk views it any more
        return tuple(np.frombuffer(mapped, np.int16, self.info.samples, o) for o in offsets)

    def _in_place(self, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
        """Samples [lo, hi) of both channels as views of the mapped file, their pages
        brought in by this thread (the chunk reader's): one touch a page maps them 16 at a
        time, about 10 ms per 400 MB here, where the device's threads would stop for them, and
        waits for the disk where the page cache does not hold them yet. A file cut since
        it was opened is an error here, where a touch of its lost pages would end the
        process."""
        if os.fstat(self._fd).st_size < max(self._map_offsets) + ITEM * hi:
            raise CaptureError(self.path, f"cannot read samples {lo}-{hi} (the file ends before them)")
        views = tuple(a[lo:hi] for a in self._mapped)
        for v, offset in zip(views, self._map_offsets, strict=True):
            if v.size:
                first = (offset + ITEM * lo) // mmap.PAGESIZE * mmap.PAGESIZE
                with contextlib.suppress(AttributeError, OSError):      # no madvise: the touches' read-ahead
                    self._mmap.madvise(mmap.MADV_WILLNEED, first, offset + ITEM * hi - first)
                v[:: mmap.PAGESIZE // ITEM].max()
        return views

    def close(self) -> None:
        for pair in self._slots:      # the slots go back to the pool for the next capture
            for a in pair:
                pool.give(a)
        self._slots = []
        self.held = None
        if self._mmap is not None:
            self._mapped = None         # the views of it here: a reader thread unmaps it
            unmap_later(self._mmap)
            self._mmap = None
        self._file.close()
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def read(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Samples [start, stop) of (beat, sync) as int16 ADC codes (clipped to the file),
        in new arrays."""
        n = max(0, min(self.info.samples, int(stop)) - max(0, int(start)))
        return self.read_into(start, stop, np.empty(n, np.int16), np.empty(n, np.int16))

    def read_into(self, start: int, stop: int, beat: np.ndarray, sync: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """`read` into the given int16 arrays (long enough): their first stop - start
        samples, as views. Reading into arrays that exist costs a fifth of the CPU of
        new ones (no pages to fault in and free: 85 against 470 ms per 333 MB here)."""
        start = max(0, int(start))
        stop = min(self.info.samples, int(stop))
        n = max(0, stop - start)
        try:
            for ds, ext, out in ((self._beat, self._extents[0], beat), (self._sync, self._extents[1], sync)):
                if n and ext is not None and out.dtype == np.int16 and out.flags.c_contiguous:
                    ext.read(self._fd, start, stop, out)
                elif n:
                    ds.read_direct(out, np.s_[start:stop], np.s_[0:n])
        except (OSError, ValueError, TypeError) as exc:
            raise CaptureError(self.path, f"cannot read samples {start}-{stop} ({exc})") from None
        return beat[:n], sync[:n]

    def read_spans(self, spans: list[tuple[int, int]], beats: list[np.ndarray], syncs: list[np.ndarray]
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
        """`read_into` of each (start, stop) of `spans` into beats[i] and syncs[i]: all at
        once on the reader threads where both channels are read straight from the file
        (`fmcw_cl.extents`: a plan's stretches, some 40 MB, no longer copied by the
        converting thread alone), else one after another."""
        bounds = [(max(0, int(a)), min(self.info.samples, int(b))) for a, b in spans]
        arrays = [*beats, *syncs]
        if not all(e is not None for e in self._extents) or any(
                a.dtype != np.int16 or not a.flags.c_contiguous for a in arrays):
            return [self.read_into(a, b, beat, sync)
                    for (a, b), beat, sync in zip(spans, beats, syncs, strict=True)]
        reads = [(ext, self._fd, a, b, out) for ext, outs in zip(self._extents, (beats, syncs), strict=True)
                 for (a, b), out in zip(bounds, outs, strict=True) if b > a]
        try:
            read_all(reads)
        except OSError as exc:
            first, last = min(a for a, _ in bounds), max(b for _, b in bounds)
            raise CaptureError(self.path, f"cannot read samples {first}-{last} ({exc})") from None
        return [(beat[: max(0, b - a)], sync[: max(0, b - a)])
                for (a, b), beat, sync in zip(bounds, beats, syncs, strict=True)]

    def slot(self, i: int, samples: int) -> tuple[np.ndarray, np.ndarray]:
        """Int16 arrays of `samples` (beat, sync) for `read_into`, slot i of those this
        capture holds: borrowed from `fmcw_cl.pool` and given back when the capture is
        closed, so that memory is touched once per process, not per capture or chunk
        (the chunks take turns in slots 0 .. chunks.READ_SLOTS - 1, the sync delay's
        stretches use slot 1, the delay refinement's held chunks slot chunks.HELD_SLOT).
        What a slot held is overwritten by its next user, after `close` by another
        capture."""
        with self._slots_lock:
            while len(self._slots) <= i:
                self._slots.append((np.empty(0, np.int16), np.empty(0, np.int16)))
            if self._slots[i][0].size < samples:
                for a in self._slots[i]:
                    pool.give(a)
                self._slots[i] = (pool.lease(samples), pool.lease(samples))
            return self._slots[i][0][:samples], self._slots[i][1][:samples]

    def chunks(self, periods: int, margin: int = 0, start: int = 0, stop: int | None = None,
               slots: int = 0, held: int | None = None) -> Iterator[Chunk]:
        """Iterate over the capture in chunks of whole modulation periods.

        Parameters
        ----------
        periods : int
            Modulation periods per chunk core; the core is round(periods * P) samples
            with P = sample_rate / modulation frequency.
        margin : int
            Extra samples read on each side of the core (clipped at the file ends).
        start, stop : int
            Sample range to cover (default: the whole capture).
        slots : int
            0: every chunk in new arrays. k > 0: the chunks take turns in the capture's
            slots 0 .. k - 1 (`slot`), so chunk i's samples are overwritten by chunk
            i + k's: for a consumer that is done with a chunk k - 1 chunks later. A
            capture opened `in_place` whose channels lie raw in the file gives views
            of the file's pages instead (read-only).
        held : int, optional
            Chunk i in slot `held` + i, its own, of its own length instead (a consumer
            that keeps every chunk: the arrays are the pool's, touched before).
        """
        size = min(self.info.core_samples(periods) + 2 * margin, self.info.samples)
        for i, (lo, hi, core_start, core_stop) in enumerate(self.chunk_spans(periods, margin, start, stop)):
            if held is not None:
                beat, sync = self.read_into(lo, hi, *self.slot(held + i, hi - lo))
            elif not slots:
                beat, sync = self.read(lo, hi)
            elif self._mapped is not None:
                beat, sync = self._in_place(lo, hi)
            else:
                beat, sync = self.read_into(lo, hi, *self.slot(i % slots, size))
            yield Chunk(lo, beat, sync, core_start, core_stop)

    def chunk_spans(self, periods: int, margin: int = 0, start: int = 0, stop: int | None = None
                    ) -> Iterator[tuple[int, int, int, int]]:
        """The samples (start, stop, core start, core stop) of each chunk of `chunks`."""
        if periods < 1:
            raise ValueError("periods must be >= 1")
        stop = self.info.samples if stop is None else min(stop, self.info.samples)
        core = self.info.core_samples(periods)
        for core_start in range(int(start), stop, core):
            core_stop = min(core_start + core, stop)
            hi = min(self.info.samples, core_stop + margin)
            yield max(0, core_start - margin), hi, core_start, core_stop

    def truth(self) -> Truth | None:
        """The simulator's true trajectory, or None when the capture has none."""
        if not self.info.has_truth:
            return None
        return _read_truth(self._file["truth"])

    def truth_objects(self) -> list[Truth]:
        """The simulator's truth of every echo of the scene, the target first, then the
        other moving echoes and the static reflectors (`Truth.kind`), each with where it
        can be seen; [] when the capture has no truth."""
        if not self.info.has_truth:
            return []
        g = self._file["truth"]
        others = g.get("objects", {})
        return [_read_truth(g), *(_read_truth(others[k]) for k in sorted(others, key=int))]


class CaptureWriter:
    """Write a capture chunk by chunk; the file appears under its name only when closed.

    Parameters
    ----------
    path : path-like
        Destination file.
    samples : int
        Total samples per channel (the datasets are created at full size).
    sample_rate_hz, bits, modulation :
        ADC and modulation description (contract section 1).
    tuning_current_a, tuning_frequency_hz : array_like
        The offline G(I) table (A, absolute Hz).
    refractive_index : float, optional
        Written to /optics when not None.
    compression : str, optional
        HDF5 filter for the ADC channels ("gzip" for small sample files, in chunks of
        1 Mi samples). None stores each channel in one run of the file, which a CPU's
        processor reads in place (`Capture` `in_place`).
    """

    def __init__(self, path, samples: int, sample_rate_hz: float, bits: int, modulation: Modulation,
                 tuning_current_a, tuning_frequency_hz, refractive_index: float | None = None,
                 compression: str | None = None, attrs: dict | None = None) -> None:
        self.path = Path(path)
        self._atomic = atomic_path(self.path)
        tmp = self._atomic.__enter__()
        try:
            self._file = h5py.File(tmp, "w")
            f = self._file
            f.attrs["fmcw_format"] = FORMAT
            f.attrs["format_version"] = FORMAT_VERSION
            for k, v in (attrs or {}).items():
                f.attrs[k] = v
            adc = f.create_group("adc")
            adc.attrs["sample_rate_hz"] = float(sample_rate_hz)
            adc.attrs["bits"] = int(bits)
            opts = {"compression": compression, "shuffle": True, "chunks": (min(samples, 1 << 20),)} \
                if compression else {}
            self.beat = adc.create_dataset("beat", (samples,), np.int16, **opts)
            self.sync = adc.create_dataset("sync", (samples,), np.int16, **opts)
            mod = f.create_group("modulation")
            mod.attrs["waveform"] = modulation.waveform
            mod.attrs["frequency_hz"] = float(modulation.frequency_hz)
            mod.attrs["current_min_a"] = float(modulation.current_min_a)
            mod.attrs["current_max_a"] = float(modulation.current_max_a)
            laser = f.create_group("laser")
            laser.create_dataset("tuning_current_a", data=np.asarray(tuning_current_a, np.float64))
            laser.create_dataset("tuning_frequency_hz", data=np.asarray(tuning_frequency_hz, np.float64))
            if refractive_index is not None:
                f.create_group("optics").attrs["refractive_index"] = float(refractive_index)
        except BaseException as exc:
            self._abort(exc)
            raise

    def set_bits(self, bits: int) -> None:
        """The ADC's resolution, where it is known only once the codes are written."""
        self._file["adc"].attrs["bits"] = int(bits)

    def write(self, start: int, beat: np.ndarray, sync: np.ndarray) -> None:
        """Store samples [start, start + len) of both channels."""
        self.beat[start:start + beat.size] = beat
        self.sync[start:start + sync.size] = sync

    def write_truth(self, truth: Truth, others: tuple[Truth, ...] = ()) -> None:
        """The target's `truth` in /truth, the scene's other echoes' in /truth/objects/<k>."""
        g = self._file.require_group("truth")
        for t, where in [(truth, g)] + [(o, g.create_group(f"objects/{k}")) for k, o in enumerate(others, 1)]:
            for name in TRUTH_FIELDS:
                where.create_dataset(name, data=np.asarray(getattr(t, name), np.float64))
            if t.visible is not None:
                where.create_dataset("visible", data=np.asarray(t.visible, bool))
            if where is not g:
                where.attrs["kind"] = t.kind

    def _abort(self, exc: BaseException) -> None:
        f = getattr(self, "_file", None)
        if f is not None:
            f.close()
        self._atomic.__exit__(type(exc), exc, exc.__traceback__)

    def close(self) -> None:
        self._file.close()
        self._atomic.__exit__(None, None, None)

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc is None:
            self.close()
        else:
            self._abort(exc)
