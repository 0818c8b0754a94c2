"""A track as a table (pandas) or a labelled dataset (xarray), and written as CSV,
Parquet or NetCDF (`fmcw-cl export`). pandas, pyarrow, xarray and h5netcdf are optional
(`pip install ".[tables]"` in the fmcw-cl folder): a missing one is named in one line.
"""

from __future__ import annotations

import importlib
import os
from pathlib import Path

import numpy as np

from .atomic import atomic_path
from .errors import FmcwError
from .stages.faults import REASONS

FORMATS = {"csv": ".csv", "parquet": ".parquet", "netcdf": ".nc"}
UNITS = {"time_s": "s", "distance_m": "m", "velocity_mps": "m/s", "acceleration_mps2": "m/s^2",
         "distance_uncertainty_m": "m", "velocity_uncertainty_mps": "m/s",
         "acceleration_uncertainty_mps2": "m/s^2", "displacement_m": "m", "displacement_uncertainty_m": "m",
         "phase_rad": "rad",
         "snr_db": "dB", "distance_dechirped_m": "m", "snr_dechirped_db": "dB"}


def optional(module: str, what: str):
    """Import an optional dependency, or say in one line how to get it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise FmcwError(f"{what} needs {module.split('.')[0]}: pip install \".[tables]\" (in the fmcw-cl "
                        "folder)") from None


def plain_attrs(attrs: dict) -> dict:
    """Attributes as Python scalars and strings (JSON- and NetCDF-safe; booleans as 0/1;
    arrays, such as target_band_m, as comma-separated numbers)."""
    out = {}
    for k, v in attrs.items():
        v = v.item() if isinstance(v, np.generic) else v
        if isinstance(v, np.ndarray):
            v = ", ".join(f"{x:g}" for x in v.ravel())
        out[k] = int(v) if isinstance(v, bool) else v
    return out


def _reason_names(codes) -> list[str] | None:
    return None if codes is None else [REASONS.get(int(c), str(int(c))) for c in codes]


def columns(track, per: str = "pair") -> dict[str, np.ndarray]:
    """The columns of one table of `track`: per "pair" (the target's, with its object
    id), "object" (the pairs of every object of the scene, with their object's id and
    kind), "sweep" or "echo"."""
    if per == "object":
        scene = track.objects or []
        if not scene:
            raise FmcwError("this track lists no objects (written before /objects existed)")
        tables = [columns(o.track, "pair") | {"object": np.full(o.track.pairs, o.id),
                                               "kind": np.full(o.track.pairs, o.kind)} for o in scene]
        names = ["object", "kind"] + [k for k in tables[0] if k not in ("object", "kind")
                                      and all(k in t for t in tables)]
        return {k: np.concatenate([t[k] for t in tables]) for k in names}
    if per == "pair":
        cols = {"object": None if track.attrs.get("target_object") is None
                else np.full(track.pairs, int(track.attrs["target_object"])),
                "time_s": track.time_s, "distance_m": track.distance_m, "velocity_mps": track.velocity_mps,
                "acceleration_mps2": track.acceleration_mps2, "valid": track.valid,
                "velocity_valid": track.velocity_valid, "acceleration_valid": track.acceleration_valid,
                "distance_uncertainty_m": track.distance_uncertainty_m,
                "velocity_uncertainty_mps": track.velocity_uncertainty_mps,
                "acceleration_uncertainty_mps2": track.acceleration_uncertainty_mps2,
                "displacement_m": track.displacement_m, "displacement_valid": track.displacement_valid,
                "displacement_uncertainty_m": track.displacement_uncertainty_m,
                "displacement_stretch": track.displacement_stretch,
                "reason": _reason_names(track.reason), "integrated_sweeps": track.integrated,
                "time_resolution_s": track.time_resolution_s}
    elif per == "sweep":
        cols = {"time_s": track.sweep_time_s, "current_rising": track.sweep_rising,
                "distance_m": track.sweep_distance_m, "snr_db": track.sweep_snr_db,
                "distance_dechirped_m": track.sweep_distance_dechirped_m,
                "snr_dechirped_db": track.sweep_snr_dechirped_db, "phase_rad": track.sweep_phase_rad,
                "reason": _reason_names(track.sweep_reason)}
    elif per == "echo":
        e = track.echoes
        if e is None:
            raise FmcwError("this track lists no echoes (written before /echoes existed)")
        cols = {"time_s": e.time_s, "distance_m": e.distance_m, "snr_db": e.snr_db,
                "current_rising": e.rising, "tracked": e.tracked}
    else:
        raise FmcwError(f"per={per!r} is not one of pair, object, sweep, echo")
    return {k: v for k, v in cols.items() if v is not None}


def to_pandas(track, per: str = "pair"):
    """A DataFrame of one table (see `columns`), the track's attributes in `.attrs`;
    `reason` is categorical (the reason codes' names)."""
    pd = optional("pandas", "to_pandas")
    df = pd.DataFrame(columns(track, per))
    if "reason" in df:
        df["reason"] = pd.Categorical(df["reason"], categories=list(REASONS.values()))
    df.attrs.update(plain_attrs(track.attrs))
    df.attrs["table"] = per
    return df


def to_xarray(track):
    """A Dataset: the pairs along `time_s`, the half-sweeps along `sweep_time_s`, units
    as variable attributes, the track's attributes on the dataset."""
    xr = optional("xarray", "to_xarray")
    data = {}
    for per, dim in (("pair", "time_s"), ("sweep", "sweep_time_s")):
        for name, values in columns(track, per).items():
            if name == "time_s":
                continue
            key = name if per == "pair" else f"sweep_{name}"
            values = np.asarray(values).astype(str) if name == "reason" else np.asarray(values)
            data[key] = xr.Variable(dim, values, {"units": UNITS[name]} if name in UNITS else {})
    coords = {"time_s": ("time_s", track.time_s, {"units": "s", "long_name": "pair centre time"}),
              "sweep_time_s": ("sweep_time_s", track.sweep_time_s,
                               {"units": "s", "long_name": "half-sweep centre time"})}
    return xr.Dataset(data, coords=coords, attrs=plain_attrs(track.attrs))


def export(track, path: str | os.PathLike, fmt: str, per: str = "pair") -> Path:
    """Write `track` as `fmt` ("csv" or "parquet": the `per` table; "netcdf": the whole
    dataset) to `path`, atomically."""
    path = Path(path)
    if fmt not in FORMATS:
        raise FmcwError(f"format {fmt!r} is not one of {', '.join(FORMATS)}")
    if fmt == "netcdf":
        ds = to_xarray(track)
        optional("h5netcdf", "NetCDF export")
        with atomic_path(path) as tmp:
            ds.to_netcdf(tmp, engine="h5netcdf")
        return path
    df = to_pandas(track, per)
    with atomic_path(path) as tmp:
        if fmt == "csv":
            df.to_csv(tmp, index=False)
        else:
            optional("pyarrow", "Parquet export")
            df.to_parquet(tmp, index=False)
    return path
