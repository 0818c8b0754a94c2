"""The command line as a user runs it: simulate, info, process, errors."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import click
import h5py
import numpy as np
import pytest

from fmcw_cl.track import read_track


def test_simulate_info_process(tmp_path, fmcw):
    cap = tmp_path / "st.h5"
    fmcw("simulate", "static", "-o", cap, "--distance", "0.2", "--duration", "0.01", "--seed", "3")
    info = fmcw("info", cap).stdout
    assert "200.0 modulation periods" in info and "truth          yes" in info
    bandwidth = float(re.search(r"sweep\s+([\d.]+) GHz", info).group(1))
    assert abs(bandwidth - 160.0) < 0.1
    out = tmp_path / "tracks"
    res = fmcw("process", cap, "-o", out, "--json")
    summary = json.loads(res.stdout)[0]
    assert summary["pairs"] == 198 and summary["valid_share"] == 1.0
    track_file = out / "st.track.h5"
    with h5py.File(track_file) as f:
        assert f.attrs["fmcw_format"] == "track" and f.attrs["format_version"] == 1
        for name in ("points", "device", "software", "sync_delay_samples", "source"):
            assert name in f.attrs
        for ds, dtype in (("sweeps/time_s", "f8"), ("sweeps/current_rising", "b1"),
                          ("sweeps/distance_m", "f8"), ("sweeps/snr_db", "f4"),
                          ("track/time_s", "f8"), ("track/distance_m", "f8"),
                          ("track/velocity_mps", "f8"), ("track/acceleration_mps2", "f8"),
                          ("track/valid", "b1")):
            assert f[ds].dtype == np.dtype(dtype), ds
        assert f["sweeps/time_s"].shape[0] == 2 * f["track/time_s"].shape[0]
    track = read_track(track_file)
    assert np.all(np.abs(track.distance_m - 0.2) < 1e-4)
    assert np.all(np.diff(track.time_s) > 0)


def test_a_g_of_i_table_of_few_points(tmp_path, static_capture, fmcw):
    """The contract's least G(I) table, 4 points: converted, its distance scale's
    uncertainty unknown (NaN), and `info` says so rather than print a number."""
    few = tmp_path / "few.h5"
    shutil.copy(static_capture, few)
    with h5py.File(few, "r+") as f:
        cur, freq = f["laser/tuning_current_a"][()], f["laser/tuning_frequency_hz"][()]
        pick = np.linspace(0, cur.size - 1, 4).round().astype(int)
        for name, x in (("tuning_current_a", cur[pick]), ("tuning_frequency_hz", freq[pick])):
            del f["laser/" + name]
            f["laser/" + name] = x
    info = fmcw("info", few).stdout
    assert "distance scale unknown: 4 G(I) points" in info and "nan" not in info
    fmcw("process", few, "-o", tmp_path / "o", "-q")
    track = read_track(tmp_path / "o" / "few.track.h5")
    assert track.valid.mean() > 0.9 and np.isnan(track.attrs["scale_uncertainty_ppm"])


def test_bad_capture_one_line_and_others_still_converted(tmp_path, static_capture, fmcw):
    bad = tmp_path / "bad.h5"
    bad.write_text("this is no hdf5")
    out = tmp_path / "tracks"
    res = fmcw("process", bad, static_capture, "-o", out, "-q", check=False)
    assert res.returncode == 1
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and "Traceback" not in res.stderr
    assert (out / "static.track.h5").exists()
    assert not (out / "bad.track.h5").exists()
    assert not list(out.glob("*.part"))


def test_skip_existing_resumes_a_batch(tmp_path, static_capture, fmcw):
    out = tmp_path / "tracks"
    fmcw("process", static_capture, "-o", out, "-q")
    done = out / "static.track.h5"
    stamp = done.stat().st_mtime_ns
    res = fmcw("process", static_capture, "-o", out, "--skip-existing", "--json")
    assert json.loads(res.stdout) == [{"capture": str(static_capture), "skipped": "its track exists"}]
    assert done.stat().st_mtime_ns == stamp
    assert "note: skipping 1 existing track in" in res.stderr and "static.h5" in res.stderr
    assert "1 capture: 0 converted, 0 failed, 1 skipped" in res.stderr
    res = fmcw("process", static_capture, "-o", out)           # overwriting is fine, and said
    assert "note: overwriting 1 existing track" in res.stderr and done.stat().st_mtime_ns != stamp


def test_a_batch_accounts_for_every_capture(tmp_path, static_capture, fmcw):
    """An output that cannot be written fails that capture in one line; the others
    convert; the batch ends with its account and --json lists the failure."""
    out = tmp_path / "tracks"
    (out / "blocked.track.h5").mkdir(parents=True)            # the track's name is taken by a folder
    blocked = tmp_path / "blocked.h5"
    blocked.write_bytes(static_capture.read_bytes())
    bad = tmp_path / "bad.h5"
    bad.write_text("no hdf5")
    res = fmcw("process", static_capture, blocked, bad, "-o", out, "--json", check=False)
    assert res.returncode == 1 and "Traceback" not in res.stderr
    errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 2 and "blocked.track.h5: cannot write it (Is a directory)" in errors[0]
    assert "3 captures: 1 converted, 2 failed, 0 skipped" in res.stderr
    records = json.loads(res.stdout)
    assert [("error" in r, Path(r["capture"]).name) for r in records] == \
        [(False, "static.h5"), (True, "blocked.h5"), (True, "bad.h5")]
    assert (out / "static.track.h5").exists() and not list(out.glob("*.part"))


@pytest.mark.parametrize(("args", "words"), [
    (["process", "{cap}", "-o", "{file}/sub"], ["{file}/sub", "cannot make the output folder"]),
    (["process", "{cap}", "-o", "{tmp}/o", "--scheduler", "bogus"], ["--scheduler 'bogus'"]),
    (["process", "{cap}", "-o", "{tmp}/o", "--device", "9"], ["no OpenCL device '9'"]),
    (["process", "{cap}", "-o", "{tmp}/o", "--max-range", "5"], ["--max-range 5 m", "unambiguous range",
                                                                  "--points"]),
    (["process", "{cap}", "-o", "{tmp}/o", "--points", "0"], ["--points 0 is below 16"]),
    (["process", "{cap}", "-o", "{tmp}/o", "--target-near", "5"], ["static.h5: --target-near 5 m",
                                                                    "beyond the unambiguous range 0.468 m"]),
    (["simulate", "static", "-o", "{tmp}/s.h5", "--duration", "-1"], ["--duration -1 s", "at least"]),
    (["simulate", "static", "-o", "{tmp}/s.h5", "--duration", "0"], ["--duration 0 s", "at least"]),
    (["simulate", "static", "-o", "{tmp}/s.h5", "--seed", "-3"], ["--seed -3 must be 0 or more"]),
    (["simulate", "static", "-o", "{cap}"], ["static.h5: exists", "--overwrite"]),
    (["bench", "--seconds", "0"], ["--seconds", "0.005"]),
    (["bench", "--seconds", "-1"], ["--seconds"]),
    (["bench", "--points", "8"], ["--points"]),
])
def test_first_hour_mistakes_are_one_line(tmp_path, static_capture, fmcw, args, words):
    (tmp_path / "afile").write_text("")
    fill = {"cap": static_capture, "file": tmp_path / "afile", "tmp": tmp_path}
    res = fmcw(*[a.format(**fill) for a in args], check=False)
    lines = res.stderr.strip().splitlines()
    assert res.returncode != 0 and lines and lines[0].startswith("error:"), res.stderr
    assert all(not line.startswith(("Traceback", "Usage")) for line in lines), res.stderr
    assert len([line for line in lines if not line.startswith("1 capture:")]) == 1, res.stderr
    for w in words:
        assert w.format(**fill) in lines[0], res.stderr


def test_the_api_names_keywords_where_the_command_line_names_flags(static_capture):
    import fmcw_cl
    from fmcw_cl.errors import FmcwError

    with pytest.raises(FmcwError, match=r"^points=0 is below 16"):
        fmcw_cl.process(static_capture, points=0)
    with pytest.raises(FmcwError, match=r"^max_range=5 m lies beyond the unambiguous range .* points=1000"):
        fmcw_cl.process(static_capture, max_range=5.0)


def test_a_track_prints_in_one_line(static_capture):
    import fmcw_cl

    text = repr(fmcw_cl.process(static_capture))
    assert "\n" not in text and len(text) < 120 and "pairs" in text and "% valid" in text


def test_info_agrees_with_process_on_a_sync_it_refuses(tmp_path, static_capture, fmcw):
    """A sync at another frequency than /modulation says: `info` gives no delay, it names
    the problem `process` refuses the capture for, and neither prints a library warning."""
    bad = tmp_path / "wrong_sync.h5"
    bad.write_bytes(static_capture.read_bytes())
    with h5py.File(bad, "r+") as f:
        n = f["adc/sync"].shape[0]
        f["adc/sync"][:] = (3000 * np.sin(2 * np.pi * np.arange(n) / 7000)).astype(np.int16)
    info = fmcw("info", bad)
    proc = fmcw("process", bad, "-o", tmp_path / "o", check=False)
    problem = "the sync repeats every 70.00 us"
    assert f"sync delay     none: {problem}" in info.stdout and "process refuses" in info.stdout
    assert proc.returncode == 1 and problem in proc.stderr
    assert "Warning" not in info.stderr + proc.stderr


def test_devices_lists_and_marks_one(fmcw):
    out = fmcw("devices").stdout.splitlines()
    assert sum(line.startswith("*") for line in out) == 1


def test_help_names_what_each_option_takes_and_gives(fmcw):
    def helped(*cmd):
        return " ".join(fmcw(*cmd, "--help").stdout.split())

    assert "--chirp FILE" in helped("process")
    assert "--points INTEGER RANGE Resampling intervals per half-sweep" in helped("bench")
    report = helped("report")
    assert "kinematics.png, echoes.png," in report
    assert "the farthest moment where the target is slow" in report


def test_simulate_a_labs_instrument(tmp_path, fmcw):
    """--lab: the weak intensity triangle leaves the first delay estimate unreliable, the
    target refines it; --no-headroom: noise peaks at full scale, counted by info."""
    lab = tmp_path / "lab.h5"
    said = fmcw("simulate", "static", "-o", lab, "--lab", "--distance", "0.4", "--seed", "2").stdout
    true = float(re.search(r"sync lags optics by ([-+\d.]+)", said).group(1))
    info = fmcw("info", lab).stdout
    got = float(re.search(r"sync lags the optics by ([-+\d.]+) \+-", info).group(1))
    assert abs(got - true) <= 1.0 and "misfit" in info and "UNRELIABLE" in info
    loud = tmp_path / "loud.h5"
    fmcw("simulate", "static", "-o", loud, "--noise", "3000", "--no-headroom", "--duration", "0.01", "-q")
    share = float(re.search(r"codes at full scale \(([\d.]+) %\)", fmcw("info", loud).stdout).group(1))
    assert 0.4 < share < 1.0


def test_help_shows_examples(fmcw):
    for cmd in ("process", "simulate", "info", "devices", "import", "report", "bench"):
        assert "Example:" in fmcw(cmd, "--help").stdout


@pytest.mark.parametrize("sample", ["static_0p3m", "jump_takeoff"])
def test_shipped_samples_convert_without_warnings(tmp_path, fmcw, sample):
    """The shipped captures (the README's first command converts the static one):
    every pair valid and no warning. The take-off's leg never stands still, so the
    tuning check de-chirps its peaks (plain ones read 3.1x the window's width)."""
    from pathlib import Path

    path = Path(__file__).parents[1] / "data_samples" / f"{sample}.h5"
    proc = fmcw("process", path, "-o", tmp_path)
    assert "warning" not in proc.stdout + proc.stderr
    track = read_track(next(tmp_path.glob("*.h5")))
    assert track.attrs["tuning_matches"] and track.valid.all()


def test_bench_rows_for_both_backends(fmcw, tmp_path):
    """`bench --json`: every stage for each backend, with the device and figures that
    agree with each other (a benchmark, so no speed is asserted); its captures kept in
    `--captures` for the next run."""
    rows = json.loads(fmcw("bench", "--seconds", "0.01", "--json", "--captures", tmp_path / "caps").stdout)
    assert sorted(p.name for p in (tmp_path / "caps").iterdir()) == [
        "bench_jump_0.01s.h5", "bench_rail_0.01s.h5", "bench_static_0.01s.h5"]
    stages = {r["stage"] for r in rows}
    scenes = {"end to end, static target", "end to end, jump (0.01 s)"}       # apart from the shares
    assert {"sync turning points", "resample", "de-chirp + FFT + peak",
            "end to end (file to track)"} | scenes <= stages
    for backend in ("numpy", "opencl"):
        mine = [r for r in rows if r["backend"] == backend]
        assert len(mine) == len(stages)
        for r in mine:
            assert r["seconds"] > 0 and r["device"]
            assert r["real_time_multiple"] == pytest.approx(0.01 / r["seconds"])
            assert r["half_sweeps_per_s"] == pytest.approx(r["real_time_multiple"] * 40_000, rel=0.01)
            share = r["share_of_end_to_end"]
            if r["stage"] in scenes | {"resample + FFT + peak + echoes", "end to end, paper's method"}:
                assert share != share                         # wholes of their own, not parts
            else:
                assert 0 < share and (share == 1) == (r["stage"] == "end to end (file to track)")
        parts = [r["share_of_end_to_end"] for r in mine if r["share_of_end_to_end"] < 1]
        assert 0 < sum(parts) < 1                             # the parts do not overlap
        ends = [r for r in mine if r["stage"].startswith("end to end")]
        assert len(ends) == 4
        for r in ends:       # where the time goes: host CPU, and the device's traffic per chunk
            assert r["host_cpu_ms_per_s"] > 0 and 0 < r["host_share_of_wall"] <= 1.05
            assert r["chunks"] >= 1
            if backend == "opencl":
                assert r["launches_per_chunk"] >= 3 and r["downloads_per_chunk"] >= 1
                assert 0 < r["device_busy_share"] <= 1.05
            else:
                assert "launches_per_chunk" not in r


def test_realistic_sample_tracks_the_moving_target_and_says_so(tmp_path, fmcw):
    """The shipped lab scene: in flight the smeared target is never a sharp echo and the
    wall would win the band; the wall is found fixed and the target moving, the wall is
    left out of the band and a note says so; --max-range does the same by hand."""
    from pathlib import Path

    from fmcw_cl.capture import Capture
    from fmcw_cl.evaluate import accuracy

    path = Path(__file__).parents[1] / "data_samples" / "jump_wall_fading.h5"
    runs = (("a", (), "leaving out the fixed echo at 0.420 m"), ("b", ("--max-range", "0.40"), ""))
    for out, args, said in runs:
        proc = fmcw("process", path, "-o", tmp_path / out, *args)
        assert said in proc.stderr and "stronger than the tracked target" not in proc.stderr, proc.stderr
        track = read_track(next((tmp_path / out).glob("*.h5")))
        with Capture(path) as cap:
            acc = accuracy(track, cap.truth())
        assert acc["valid_share"] >= 0.95
        assert acc["distance_max_m"] <= 0.5e-3


def test_simulate_a_scene_and_refuse_bad_options(tmp_path, fmcw):
    cap = tmp_path / "scene.h5"
    fmcw("simulate", "static", "-o", cap, "--distance", "0.2", "--duration", "0.005", "--snr-db", "0",
         "--reflector", "0.33:600", "--speckle-ms", "2", "--table-noise-mhz", "20", "--rin-db-hz", "-140",
         "-q")
    res = json.loads(fmcw("process", cap, "-o", tmp_path / "t", "--json", "--max-range", "0.3").stdout)[0]
    assert res["rival_echo"] is None                   # the reflector lies beyond --max-range
    track = read_track(tmp_path / "t" / "scene.track.h5")
    assert np.any(np.abs(track.echoes.persistent["distance_m"] - 0.33) < 2e-3)
    for bad, word in ((["--reflector", "0.3"], "DIST:AMPLITUDE"), (["--reflector", "-1:5"], "> 0 m"),
                      (["--noise", "5", "--snr-db", "0"], "not both")):
        proc = fmcw("simulate", "static", "-o", tmp_path / "x.h5", *bad, check=False)
        assert proc.returncode != 0 and word in proc.stderr
    proc = fmcw("process", cap, "-o", tmp_path / "u", "--max-range", "0.02", check=False)
    assert proc.returncode == 1 and "--max-range" in proc.stderr and proc.stderr.count("\n") == 1


HEAVY = ("scipy", "matplotlib", "pyopencl", "dask")


def _imported_by(*argv: str) -> set[str]:
    """Top-level packages a fresh interpreter has imported after `fmcw-cl ARGV`."""
    code = ("import sys\nfrom fmcw_cl.cli.main import main\n"
            f"try:\n    main({list(argv)!r})\nexcept SystemExit:\n    pass\n"
            "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})), file=sys.stderr)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    return set(proc.stderr.split())


def test_start_up_imports_only_what_the_command_needs():
    """`fmcw-cl --help` answers at once: not even numpy or h5py. `info` converts the sync
    delay's stretches as `process` does (scipy, the numpy stages), but never matplotlib,
    pyopencl or Dask."""
    assert not _imported_by("--help") & {*HEAVY, "numpy", "h5py"}
    sample = str(Path(__file__).parents[1] / "data_samples" / "static_0p3m.h5")
    got = _imported_by("info", sample)
    assert "h5py" in got and not got & (set(HEAVY) - {"scipy"})


def test_command_table_matches_the_commands():
    from fmcw_cl.cli.main import COMMANDS, cli

    ctx = click.Context(cli)
    for name, (_, line) in COMMANDS.items():
        assert cli.get_command(ctx, name).help.strip().splitlines()[0] == line
