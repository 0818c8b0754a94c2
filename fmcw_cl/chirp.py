"""Chirp calibration files (`fmcw-cl calibrate`, `process --chirp`) and the LUT they give.

A chirp file holds, per sweep direction, the optical frequency measured against time
over the half-sweep: the time as a fraction s of the half-sweep that the pipeline cuts
from the sync (s = 0 at the turning point of the sync, moved by the capture's sync
delay; the optics may lag it, so the measured stretch can reach past 0 and 1), and the
frequency relative to its middle (Hz). Layout in docs/formats.md.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from .atomic import atomic_hdf5
from .errors import CaptureError, FmcwError
from .stages.lut import Lut

FORMAT = "chirp"
FORMAT_VERSION = 1


@dataclass(frozen=True)
class Direction:
    """The measured chirp of one sweep direction.

    s : (K,) time as a fraction of the half-sweep, increasing.
    nu_hz : (K,) optical frequency relative to its middle value (Hz), monotonic.
    """

    s: np.ndarray
    nu_hz: np.ndarray

    @property
    def bandwidth_hz(self) -> float:
        return float(abs(self.nu_hz[-1] - self.nu_hz[0]))


@dataclass(frozen=True)
class Chirp:
    """A calibration: both directions and how it was made (attrs)."""

    rising: Direction
    falling: Direction
    attrs: dict = field(default_factory=dict)

    @property
    def bandwidth_hz(self) -> float:
        """The band both directions cover: the LUT's bandwidth."""
        return min(self.rising.bandwidth_hz, self.falling.bandwidth_hz)


def write_chirp(path: str | os.PathLike, chirp: Chirp) -> Path:
    """Write atomically (a temporary name renamed when complete)."""
    path = Path(path)
    with atomic_hdf5(path, FORMAT, FORMAT_VERSION, chirp.attrs) as f:
        write_directions(f, chirp)
    return path


def write_directions(group: h5py.Group, chirp: Chirp) -> None:
    """The two directions' curves as `rising/` and `falling/` of `group` (a chirp file's
    root, or a track's `/chirp`)."""
    for name in ("rising", "falling"):
        d: Direction = getattr(chirp, name)
        g = group.create_group(name)
        g.create_dataset("s", data=d.s)
        g.create_dataset("nu_hz", data=d.nu_hz)
        g.attrs["bandwidth_hz"] = d.bandwidth_hz


def read_directions(group: h5py.Group) -> tuple[Direction, Direction]:
    """The curves `write_directions` wrote (KeyError where one is missing)."""
    return tuple(Direction(np.asarray(group[n]["s"][()], float), np.asarray(group[n]["nu_hz"][()], float))
                 for n in ("rising", "falling"))


def read_chirp(path: str | os.PathLike) -> Chirp:
    """Read a chirp file; a clear CaptureError names the file when it is not one."""
    path = Path(path)
    if not path.is_file():
        raise CaptureError(path, "no such file")
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("fmcw_format") not in (FORMAT, FORMAT.encode()):
                raise CaptureError(path, "not a chirp file (fmcw_format is not 'chirp')")
            dirs = read_directions(f)
            attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
    except (OSError, KeyError) as exc:
        raise CaptureError(path, f"not a readable chirp file ({exc})") from None
    for d in dirs:
        if d.s.size < 16 or not np.all(np.diff(d.s) > 0) or not (
                np.all(np.diff(d.nu_hz) > 0) or np.all(np.diff(d.nu_hz) < 0)):
            raise CaptureError(path, "a chirp direction is not a monotonic curve")
    return Chirp(*dirs, attrs)


def chirp_lut(chirp: Chirp, points: int, nu_centre_hz: float, refractive_index: float = 1.0) -> Lut:
    """The LUT of a calibration: per direction, the instants (fractions of the
    half-sweep) of N uniformly spaced optical frequencies over the common band,
    centred in that direction's measured band, ordered by increasing frequency.

    `nu_centre_hz` (the absolute frequency of the middle, from G(I)) only sets the
    Doppler scale 2 nu / c, not the distances.
    """
    if points < 16:
        raise FmcwError(f"--points {points} is too small (at least 16)")
    band = chirp.bandwidth_hz
    offsets = (np.arange(points) + 0.5) * band / points - band / 2
    us = []
    for d in (chirp.rising, chirp.falling):
        order = np.argsort(d.nu_hz)
        nu, s = d.nu_hz[order], d.s[order]
        mid = 0.5 * (nu[0] + nu[-1])
        us.append(np.interp(mid + offsets, nu, s))
    return Lut(points, us[0], us[1], nu_centre_hz + offsets, float(band), float(refractive_index))


def check_chirp(chirp: Chirp, info, chirp_path) -> None:
    """A calibration applies only to captures of the same ADC rate and modulation."""
    for key, value in (("sample_rate_hz", info.sample_rate_hz),
                       ("modulation_frequency_hz", info.modulation.frequency_hz)):
        made = chirp.attrs.get(key)
        if made is not None and abs(float(made) / value - 1) > 1e-6:
            raise CaptureError(Path(chirp_path), f"calibrated at {key} = {float(made):g}, but "
                                                 f"{info.path} has {value:g}")
