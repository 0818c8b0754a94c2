"""The Python API as a user calls it: docs/api.md's example, options, tables, export."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

import fmcw_cl
from fmcw_cl.errors import FmcwError

ROOT = Path(__file__).parents[1]
SAMPLE = ROOT / "data_samples" / "static_0p3m.h5"


def test_the_documented_example_runs(tmp_path, monkeypatch):
    """Every ```python cell of docs/api.md, in order, in one namespace, from the repo
    root (the paths it names) writing into a temporary folder."""
    cells = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "api.md").read_text(), re.S)
    assert len(cells) >= 5
    monkeypatch.chdir(tmp_path)
    os.symlink(ROOT / "data_samples", tmp_path / "data_samples")
    ns: dict = {}
    for cell in cells:
        exec(compile(cell, "docs/api.md", "exec"), ns)  # noqa: S102 - the documented example
    assert (tmp_path / "velocity.png").stat().st_size > 1000
    assert ns["track"].pairs == len(ns["pairs"]) and ns["near"].valid.all()


def test_process_takes_the_command_line_options_by_name():
    a = fmcw_cl.process(SAMPLE, backend="numpy", points=1000, dechirp=False, range_check=False)
    assert a.attrs["dechirp"] is False or a.attrs["dechirp"] == 0
    assert not a.attrs["range_check"]
    with pytest.raises(FmcwError, match=r"points=70000 exceeds 16384"):
        fmcw_cl.process(SAMPLE, points=70000)
    with pytest.raises(FmcwError, match=r"unknown option pionts; the options are points"):
        fmcw_cl.process(SAMPLE, pionts=7)
    with pytest.raises(FmcwError, match=r"backend='cuda' is not one of auto, opencl, numpy"):
        fmcw_cl.process(SAMPLE, backend="cuda")
    with pytest.raises(FmcwError, match=r"min_range=-1 is below 0"):
        fmcw_cl.process(SAMPLE, min_range=-1)


def test_every_process_option_of_the_command_line_is_in_the_api():
    """One definition: the command's flags are those of fmcw_cl.options.PROCESS (the
    Options fields a user sets) and RUN (where it runs), plus the batch's own (output,
    resume, cluster, printing)."""
    import click
    from fmcw_cl.cli.main import cli

    from fmcw_cl.options import PROCESS, RUN

    cmd = cli.get_command(click.Context(cli), "process")
    batch = {"captures", "outdir", "skip_existing", "scheduler", "as_json", "quiet"}
    names = {p.name for p in cmd.params} - batch
    assert names == {o.name for o in PROCESS + RUN}


def test_one_validated_configuration():
    """Options is the one configuration: its fields are the specs' (PROCESS and the
    engine's own), each checked when it is made, with the numbers in the message, and
    the rule between fields; the API's keywords make the same object."""
    from dataclasses import FrozenInstanceError, fields

    from fmcw_cl.errors import FmcwError
    from fmcw_cl.options import ENGINE, PROCESS, Options, from_keywords

    assert [f.name for f in fields(Options)] == [o.name for o in PROCESS + ENGINE]
    assert all(getattr(Options(), o.name) == o.default for o in PROCESS + ENGINE)
    for bad, words in (({"points": 8}, "points=8 is below 16"),
                       ({"iterations": 0}, "iterations=0 is below 1"),
                       ({"context_periods": 2.5}, "not a whole number"),
                       ({"dechirp": "no"}, "True or False"),
                       ({"target": "loudest"}, "not one of auto"),
                       ({"chunk_periods": -3}, "below 1"),
                       ({"min_range": 0.3, "max_range": 0.305}, "max_range=0.305 m must exceed")):
        with pytest.raises(FmcwError, match=words):
            Options(**bad)
    opts = Options(points=1024.0, max_range=1)          # converted to the field's type
    assert type(opts.points) is int and type(opts.max_range) is float
    with pytest.raises(FrozenInstanceError):
        opts.points = 2
    config, backend, device = from_keywords({"max_range": 0.4, "backend": "numpy"})
    assert config == Options(max_range=0.4) and (backend, device) == ("numpy", None)
    with pytest.raises(FmcwError, match="unknown option iterationz"):
        from_keywords({"iterationz": 3})


def test_tables_and_labelled_arrays(jump_track):
    track = fmcw_cl.read_track(jump_track)
    df = track.to_pandas()
    assert list(df.columns) == ["object", "time_s", "distance_m", "velocity_mps", "acceleration_mps2",
                                "valid", "velocity_valid", "acceleration_valid", "distance_uncertainty_m",
                                "velocity_uncertainty_mps", "acceleration_uncertainty_mps2", "displacement_m",
                                "displacement_valid", "displacement_uncertainty_m", "displacement_stretch",
                                "reason"]
    assert len(df) == track.pairs and df.attrs["points"] == 1000
    assert (df.object == track.attrs["target_object"]).all()
    scene = track.to_pandas(per="object")
    assert list(scene.columns[:3]) == ["object", "kind", "time_s"]
    assert len(scene) == sum(o.track.pairs for o in track.objects)
    assert set(df.reason.cat.categories) >= {"ok", "no_echo", "discontinuous"}
    sweeps = track.to_pandas(per="sweep")
    assert len(sweeps) == track.sweep_time_s.size and sweeps.current_rising.sum() == len(sweeps) // 2
    assert len(track.to_pandas(per="echo")) == track.echoes.time_s.size
    ds = track.to_xarray()
    assert dict(ds.sizes) == {"time_s": track.pairs, "sweep_time_s": track.sweep_time_s.size}
    assert ds.distance_m.attrs["units"] == "m" and ds.acceleration_mps2.attrs["units"] == "m/s^2"
    assert ds.distance_uncertainty_m.attrs["units"] == "m"
    np.testing.assert_array_equal(ds.distance_m.values, track.distance_m)
    assert ds.attrs["unambiguous_range_m"] == track.attrs["unambiguous_range_m"]


def test_export_round_trips(jump_track, tmp_path, fmcw):
    import pandas as pd
    import xarray as xr

    track = fmcw_cl.read_track(jump_track)
    for fmt in ("csv", "parquet", "netcdf"):
        fmcw("export", jump_track, "-o", tmp_path, "--format", fmt)
    stem = Path(jump_track).name.removesuffix(".track.h5")
    back = pd.read_parquet(tmp_path / f"{stem}.parquet")
    pd.testing.assert_frame_equal(back, track.to_pandas(), check_categorical=False)
    assert back.attrs["points"] == 1000                   # the track's attributes travel along
    csv = pd.read_csv(tmp_path / f"{stem}.csv")
    np.testing.assert_allclose(csv.distance_m, track.distance_m, rtol=1e-12, equal_nan=True)
    with xr.open_dataset(tmp_path / f"{stem}.nc", engine="h5netcdf") as ds:
        xr.testing.assert_identical(ds.load(), track.to_xarray())
    assert not list(tmp_path.glob("*.part"))


def test_export_refuses_a_non_track_and_converts_the_others(tmp_path, fmcw, jump_track):
    bad = tmp_path / "bad.track.h5"
    bad.write_bytes(b"not hdf5")
    proc = fmcw("export", bad, jump_track, "-o", tmp_path / "out", check=False)
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1 and "bad.track.h5" in proc.stderr
    assert len(list((tmp_path / "out").glob("*.csv"))) == 1


def test_a_missing_optional_library_is_named(monkeypatch, jump_track):
    import builtins

    real = builtins.__import__

    def no_pandas(name, *args, **kwargs):
        if name.split(".")[0] == "pandas":
            raise ImportError(name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_pandas)
    monkeypatch.delitem(__import__("sys").modules, "pandas", raising=False)
    # the README's words: the install from the checkout
    readme = (Path(__file__).parents[1] / "README.md").read_text()
    assert 'pip install ".[tables]"' in readme
    with pytest.raises(FmcwError, match=r'to_pandas needs pandas: pip install "\.\[tables\]"'):
        fmcw_cl.read_track(jump_track).to_pandas()


def test_top_level_is_lazy_and_complete():
    assert set(fmcw_cl.__all__) >= {"process", "read_track", "write_track", "open_capture", "simulate",
                                    "calibrate", "Track"}
    for name in fmcw_cl.__all__:
        assert getattr(fmcw_cl, name) is not None
    with pytest.raises(AttributeError):
        fmcw_cl.no_such_thing  # noqa: B018


def test_process_each_by_option_names(tmp_path):
    """A batch through the API: results in order, the options by the command line's
    names, a bad file as its error while the others convert."""
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not a capture")
    got = list(fmcw_cl.process_each([SAMPLE, bad, SAMPLE], backend="numpy", dechirp=False))
    assert [Path(p) for p, _ in got] == [Path(SAMPLE), bad, Path(SAMPLE)]
    assert isinstance(got[1][1], FmcwError)
    for _, track in (got[0], got[2]):
        assert isinstance(track, fmcw_cl.Track) and track.attrs["dechirp"] is False and track.pairs > 0
