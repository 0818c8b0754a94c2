"""Track files (contract section 2): the measured trajectory, written atomically."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from .atomic import atomic_hdf5
from .chirp import Chirp, read_directions, write_directions
from .echoes import MEAN_KEYS, Echoes, no_means
from .stages.bank import POINT_KEYS, no_points
from .stages.faults import REASONS

FORMAT = "track"
FORMAT_VERSION = 1


@dataclass(repr=False)
class Track:
    """Per half-sweep and per pair results, with the parameters that made them."""

    sweep_time_s: np.ndarray
    sweep_rising: np.ndarray
    sweep_distance_m: np.ndarray
    sweep_snr_db: np.ndarray
    time_s: np.ndarray
    distance_m: np.ndarray
    velocity_mps: np.ndarray
    acceleration_mps2: np.ndarray
    valid: np.ndarray
    attrs: dict = field(default_factory=dict)
    sweep_distance_dechirped_m: np.ndarray | None = None   # after the final de-chirp
    sweep_snr_dechirped_db: np.ndarray | None = None
    reason: np.ndarray | None = None          # per pair, codes of fmcw_cl.stages.faults
    sweep_reason: np.ndarray | None = None    # per half-sweep: its pair's code
    echoes: Echoes | None = None              # every CFAR echo, and the persistent ones
    integrated: np.ndarray | None = None      # per pair, half-sweeps of a direction summed (when K varies)
    period_s: float | None = None             # modulation period (s): time resolution of one half-sweep pair
    chirp: Chirp | None = None                # the chirp that replaced the G(I) table, if one did
    velocity_valid: np.ndarray | None = None  # per pair: the velocity verified (None: as `valid`)
    acceleration_valid: np.ndarray | None = None   # ... its window whole on verified velocities
    distance_uncertainty_m: np.ndarray | None = None    # per pair: expanded uncertainty (k = 2)
    velocity_uncertainty_mps: np.ndarray | None = None
    acceleration_uncertainty_mps2: np.ndarray | None = None
    objects: list | None = None               # the scene's objects.SceneObject, the target among them
    displacement_m: np.ndarray | None = None       # per pair: from the beat's phase (fmcw_cl.displacement)
    displacement_valid: np.ndarray | None = None
    displacement_uncertainty_m: np.ndarray | None = None   # expanded (k = 2)
    displacement_stretch: np.ndarray | None = None  # its reference's stretch (-1: not valid)
    sweep_phase_rad: np.ndarray | None = None       # per half-sweep: the beat's phase at its peak

    def __post_init__(self) -> None:
        # a track written before validity per quantity: its velocities and accelerations
        # as valid as its distances
        if self.velocity_valid is None:
            self.velocity_valid = np.asarray(self.valid, bool).copy()
        if self.acceleration_valid is None:
            self.acceleration_valid = np.asarray(self.valid, bool) & np.isfinite(self.acceleration_mps2)

    @property
    def time_resolution_s(self) -> np.ndarray | None:
        """Per pair, the time its measurement spans (s): integrated sweeps x period;
        None when uniform (attribute `time_resolution_s`)."""
        if self.integrated is None:
            return None
        return self.integrated * (np.nan if self.period_s is None else self.period_s)

    @property
    def pairs(self) -> int:
        return int(self.time_s.size)

    def __repr__(self) -> str:
        """One line: what a user checks first (the arrays are the fields)."""
        span = f"{self.time_s[0]:.4f}-{self.time_s[-1]:.4f} s" if self.pairs else "empty"
        valid = f"{100 * np.mean(self.valid):.1f} % valid" if self.pairs else "no pairs"
        where = self.attrs.get("source", "")
        return (f"<Track {Path(str(where)).name + ': ' if where else ''}{self.pairs} pairs, {span}, "
                f"{valid}>")

    def to_pandas(self, per: str = "pair"):
        """A pandas DataFrame per "pair" (object, time_s, distance_m, velocity_mps,
        acceleration_mps2, valid, reason), per "object" (the pairs of every object of the
        scene, with its id and kind), per "sweep" (each half-sweep) or per "echo"; the
        attributes in `.attrs`. Needs pandas (`pip install ".[tables]"` in the
        fmcw-cl folder)."""
        from .tables import to_pandas

        return to_pandas(self, per)

    def to_xarray(self):
        """An xarray Dataset: pairs along time_s, half-sweeps along sweep_time_s, units
        as attributes, the track's attributes carried over. Needs xarray."""
        from .tables import to_xarray

        return to_xarray(self)


def track_path(outdir: str | os.PathLike, capture: str | os.PathLike) -> Path:
    """OUTDIR/<capture stem>.track.h5"""
    return Path(outdir) / f"{Path(capture).stem}.track.h5"


def write_track(path: str | os.PathLike, track: Track) -> Path:
    """Write `track` to `path` atomically (a temporary name, renamed when complete)."""
    path = Path(path)
    with atomic_hdf5(path, FORMAT, FORMAT_VERSION, track.attrs) as f:
        s = f.create_group("sweeps")
        s.create_dataset("time_s", data=np.asarray(track.sweep_time_s, np.float64))
        s.create_dataset("current_rising", data=np.asarray(track.sweep_rising, bool))
        s.create_dataset("distance_m", data=np.asarray(track.sweep_distance_m, np.float64))
        s.create_dataset("snr_db", data=np.asarray(track.sweep_snr_db, np.float32))
        if track.sweep_distance_dechirped_m is not None:
            s.create_dataset("distance_dechirped_m",
                             data=np.asarray(track.sweep_distance_dechirped_m, np.float64))
            s.create_dataset("snr_dechirped_db", data=np.asarray(track.sweep_snr_dechirped_db, np.float32))
        if track.sweep_reason is not None:
            s.create_dataset("reason", data=np.asarray(track.sweep_reason, np.uint8))
        if track.sweep_phase_rad is not None:
            s.create_dataset("phase_rad", data=np.asarray(track.sweep_phase_rad, np.float64))
        _write_pairs(f.create_group("track"), track)
        for o in track.objects or ():
            g = f.create_group(f"objects/{o.id}")
            _write_pairs(g, o.track)
            for k, v in {**{k: o.track.attrs[k] for k in OBJECT_TRACK_ATTRS if k in o.track.attrs},
                         **o.attrs()}.items():
                g.attrs[k] = v
        if track.echoes is not None:
            _write_echoes(f.create_group("echoes"), track.echoes)
        if track.chirp is not None:
            write_directions(f.create_group("chirp"), track.chirp)
    return path


def _write_pairs(t: h5py.Group, track: Track) -> None:
    """The per-pair datasets of `track` (contract: /track) into group `t`."""
    t.create_dataset("time_s", data=np.asarray(track.time_s, np.float64))
    t.create_dataset("distance_m", data=np.asarray(track.distance_m, np.float64))
    t.create_dataset("velocity_mps", data=np.asarray(track.velocity_mps, np.float64))
    t.create_dataset("acceleration_mps2", data=np.asarray(track.acceleration_mps2, np.float64))
    t.create_dataset("valid", data=np.asarray(track.valid, bool))
    if track.reason is not None:
        t.create_dataset("reason", data=np.asarray(track.reason, np.uint8))
    for name in OPTIONAL_PAIR_DATASETS:
        x = getattr(track, name)
        if x is not None:
            kind = bool if name.endswith("valid") else np.int32 if name.endswith("stretch") else np.float64
            t.create_dataset(name, data=np.asarray(x, kind))
    if track.integrated is not None:
        t.create_dataset("integrated_sweeps", data=np.asarray(track.integrated, np.uint16))
        t.create_dataset("time_resolution_s", data=np.asarray(track.time_resolution_s, np.float64))


def _read_pairs(t: h5py.Group, attrs: dict, period_s: float | None) -> Track:
    """A track of the per-pair datasets of group `t` alone (an object of /objects)."""
    optional = {name: t[key][()] for name, key in (("reason", "reason"), ("integrated", "integrated_sweeps"),
                                                   *((n, n) for n in OPTIONAL_PAIR_DATASETS)) if key in t}
    empty = np.zeros(0)
    return Track(empty, np.zeros(0, bool), empty, empty, t["time_s"][()], t["distance_m"][()],
                 t["velocity_mps"][()], t["acceleration_mps2"][()], t["valid"][()], attrs, period_s=period_s,
                 **optional)


# an object's track attributes written beside its own (fmcw_cl.objects.SceneObject.attrs)
OBJECT_TRACK_ATTRS = ("target_band_m", "target_choice", "time_resolution_s", "target_tracked_m",
                      "still_echoes_removed_s", "object_bands_m", "band_along_course",
                      *(f"invalid_{name}" for code, name in REASONS.items() if code))
OPTIONAL_PAIR_DATASETS = ("velocity_valid", "acceleration_valid", "distance_uncertainty_m",
                          "velocity_uncertainty_mps", "acceleration_uncertainty_mps2", "displacement_m",
                          "displacement_valid", "displacement_uncertainty_m", "displacement_stretch")
ECHO_COLUMNS = (("time_s", np.float64), ("distance_m", np.float64), ("snr_db", np.float32),
                ("current_rising", bool), ("tracked", bool))
PERSISTENT_COLUMNS = ("time_s", "distance_m", "snr_db", "share", "relative_db", "in_band", "diffuse")


def _write_echoes(g, e: Echoes) -> None:
    for (name, dtype), x in zip(ECHO_COLUMNS, (e.time_s, e.distance_m, e.snr_db, e.rising, e.tracked),
                                strict=True):
        g.create_dataset(name, data=np.asarray(x, dtype))
    p = g.create_group("persistent")
    for name in PERSISTENT_COLUMNS:
        flag = name in ("in_band", "diffuse")
        p.create_dataset(name, data=np.asarray(e.persistent[name], bool if flag else np.float64))
    m = g.create_group("means")
    for name in MEAN_KEYS:
        m.create_dataset(name, data=e.means[name])
    f = g.create_group("fast")
    for name in POINT_KEYS:
        f.create_dataset(name.removeprefix("fast_"), data=np.asarray(e.fast[name], np.float64))


def _read_echoes(g) -> Echoes:
    cols = [g[name][()] for name, _ in ECHO_COLUMNS]
    means = {name: g["means"][name][()] for name in MEAN_KEYS} if "means" in g else no_means()
    fast = ({name: g["fast"][name.removeprefix("fast_")][()] for name in POINT_KEYS} if "fast" in g
            else no_points())
    return Echoes(*cols, {name: g["persistent"][name][()] for name in PERSISTENT_COLUMNS
                          if name in g["persistent"]}, means, fast=fast)


def _read_objects(g: h5py.Group, period_s: float | None) -> list:
    from .objects import SceneObject

    out = []
    for key in sorted(g, key=int):
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in g[key].attrs.items()}
        out.append(SceneObject(int(key), attrs.get("object_kind") == "moving",
                               _read_pairs(g[key], attrs, period_s), str(attrs.get("object_note", ""))))
    return out


def read_track(path: str | os.PathLike) -> Track:
    """Read a track file written by `write_track` (or any writer of the contract)."""
    with h5py.File(path, "r") as f:
        if f.attrs.get("fmcw_format") != FORMAT:
            raise ValueError(f"{path}: not a track file")
        s, t = f["sweeps"], f["track"]
        attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
        optional = {name: g[key][()] for name, g, key in (
            ("sweep_distance_dechirped_m", s, "distance_dechirped_m"),
            ("sweep_snr_dechirped_db", s, "snr_dechirped_db"),
            ("sweep_reason", s, "reason"), ("reason", t, "reason"), ("sweep_phase_rad", s, "phase_rad"),
            ("integrated", t, "integrated_sweeps"),
            *((name, t, name) for name in OPTIONAL_PAIR_DATASETS)) if key in g}
        if "modulation_period_s" in attrs:
            optional["period_s"] = float(attrs["modulation_period_s"])
        if "echoes" in f:
            optional["echoes"] = _read_echoes(f["echoes"])
        if "chirp" in f:
            optional["chirp"] = Chirp(*read_directions(f["chirp"]))
        if "objects" in f:
            optional["objects"] = _read_objects(f["objects"], optional.get("period_s"))
        return Track(s["time_s"][()], s["current_rising"][()], s["distance_m"][()],
                     s["snr_db"][()], t["time_s"][()], t["distance_m"][()],
                     t["velocity_mps"][()], t["acceleration_mps2"][()], t["valid"][()], attrs,
                     **optional)
