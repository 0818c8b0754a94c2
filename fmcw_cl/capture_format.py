"""The capture contract (section 1): what a capture file holds (`CaptureInfo`,
`Modulation`, `Truth`) and the check of an open file against it (`validate`, with the
ranges of its attributes in `LIMITS`); h5py's open errors in a user's words
(`_open_problem`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from .errors import CaptureError

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
class Truth:
    """The true trajectory written by simulators (SI units)."""

    time_s: np.ndarray
    distance_m: np.ndarray
    velocity_mps: np.ndarray
    acceleration_mps2: np.ndarray
    visible: np.ndarray | None = None   # where the echo can be seen (None: always)
    kind: str = "moving"                # "moving", or "fixed" for a static reflector


TRUTH_FIELDS = ("time_s", "distance_m", "velocity_mps", "acceleration_mps2")


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
