"""`fmcw-cl process`: captures to tracks."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click
import numpy as np

from fmcw_cl import options as opts
from fmcw_cl.atomic import output_folder
from fmcw_cl.backend import make_processor
from fmcw_cl.batch import process_each
from fmcw_cl.errors import FmcwError
from fmcw_cl.progress import Progress
from fmcw_cl.stages import faults
from fmcw_cl.track import track_path, write_track


def summary(capture, out, attrs: dict, valid: np.ndarray) -> dict:
    """The facts a user checks after a conversion."""
    a = attrs
    dur = float(a["capture_duration_s"])
    secs = float(a["processing_time_s"])
    return {
        "capture": str(capture), "track": str(out), "duration_s": dur, "pairs": int(valid.size),
        "valid_share": float(np.mean(valid)) if valid.size else 0.0,
        "sync_delay_samples": float(a["sync_delay_samples"]), "device": a["device"],
        "processing_time_s": secs, "real_time_multiple": dur / secs if secs > 0 else None,
        "invalid": {name: int(a[f"invalid_{name}"]) for code, name in faults.REASONS.items()
                    if code and f"invalid_{name}" in a},
        "rival_echo": ({"distance_m": float(a["rival_echo_m"]), "relative_db": float(a["rival_echo_db"]),
                        "moving": bool(a.get("rival_echo_diffuse", False))}
                       if np.isfinite(a.get("rival_echo_m", np.nan)) else None),
        "target_object": int(a["target_object"]) if "target_object" in a else None,
        "objects": int(a.get("objects", 1)),
    }


def tracked(attrs: dict) -> str:
    """The tracked target's distances and what it is, in words."""
    lo, hi = np.asarray(attrs.get("target_tracked_m", (np.nan, np.nan)), float)
    if not np.isfinite(lo):
        return "no valid pair"
    what = "moving" if attrs.get("target_moving") else "fixed"
    return f"{what}, {lo:.3f} m" if hi - lo < 0.002 else f"{what}, {lo:.3f}-{hi:.3f} m"


def target_lines(cap, attrs: dict) -> None:
    """One line on the target choice where it left echoes out or could not decide, and
    one naming the scene's other objects, each with the option that chooses it."""
    others = attrs.get("target_others", "")
    if others and int(attrs.get("target_object", 1)):
        click.echo(f"note: {cap}: the target is object #{attrs['target_object']} of {attrs['objects']} "
                   f"({tracked(attrs)}); the others: {others}", err=True)
    elif others:
        click.echo(f"warning: {cap}: {attrs['target_choice']}; the objects: {others}", err=True)
    fixed = np.asarray(attrs.get("target_fixed_echoes_m", ()), float)
    band = np.asarray(attrs.get("target_band_m", (np.nan, np.nan)), float)
    amb = int(attrs.get("invalid_ambiguous", 0))
    choice = attrs.get("target_choice", "")
    hint = "--target, --target-near choose another"
    left = fixed[(fixed < band[0]) | (fixed >= np.nan_to_num(band[1], nan=np.inf))]
    if amb and int(attrs.get("target_object", 1)):
        click.echo(f"warning: {cap}: {amb} pairs ambiguous: {choice} ({hint})", err=True)
    elif left.size:
        top = "the end" if not np.isfinite(band[1]) else f"{band[1]:.3f} m"
        click.echo(f"note: {cap}: the target ({tracked(attrs)}) is tracked from {band[0]:.3f} m to {top}, "
                   f"leaving out the fixed echo{'es' if left.size > 1 else ''} at "
                   f"{', '.join(f'{x:.3f}' for x in left)} m ({hint})", err=True)


def delay_doubt(attrs: dict) -> str:
    """Why the sync delay may bias velocities beyond the track's stated bound, in words."""
    bound = float(attrs.get("sync_delay_velocity_bound_mps", 0.002))
    if attrs.get("sync_delay_refined"):
        return (f"the sync delay is uncertain by {attrs['sync_delay_uncertainty_samples']:.2f} samples "
                f"(velocities +-{attrs['sync_delay_velocity_uncertainty_mps']:.4f} m/s, more than "
                f"{bound:g}): the target's valid runs are short or noisy")
    return (f"no valid run of the target to align the sync delay on, and no clear intensity triangle "
            f"(misfit {attrs['sync_delay_misfit']:.2f}): velocities may be biased beyond {bound:g} m/s")


def report(s: dict, attrs: dict, quiet: bool, as_json: bool) -> None:
    """Warnings (always, on stderr) and the one-screen summary of one capture."""
    cap = s["capture"]
    if attrs["near_range_limit_pairs"]:
        click.echo(f"warning: {cap}: {attrs['near_range_limit_pairs']} pairs lie within 5 % of "
                   f"the unambiguous range ({attrs['unambiguous_range_m']:.3f} m); a farther "
                   "target would alias: raise --points", err=True)
    if not attrs["sync_delay_reliable"]:
        click.echo(f"warning: {cap}: {delay_doubt(attrs)}", err=True)
    apart = float(attrs.get("sync_delay_disagreement_sigmas", np.nan))
    if apart > float(attrs.get("sync_delay_disagreement_limit", np.inf)):
        click.echo(f"note: {cap}: the sync delay refined on the target ({attrs['sync_delay_samples']:+.2f} "
                   f"+-{attrs['sync_delay_uncertainty_samples']:.2f} samples) and the intensity triangle's "
                   f"({attrs['sync_delay_intensity_samples']:+.2f} "
                   f"+-{attrs['sync_delay_intensity_uncertainty_samples']:.2f}) are {apart:.1f} sigmas "
                   "apart: the refined one is used (the velocities depend on it; a moving target's beat "
                   "and a laser's thermal lag move the intensity's)", err=True)
    if attrs.get("rest_calibration") == "made":
        span = attrs["rest_calibration_span_s"]
        click.echo(f"note: {cap}: the laser's chirp is far from its G(I) table (peaks "
                   f"{attrs['table_peak_width_ratio']:.1f}x the window's): calibrated on its own rest "
                   f"({span[0]:.3f}-{span[1]:.3f} s at {attrs['rest_calibration_distance_m']:.4f} m), the "
                   f"distance scale set by its motion (+-{attrs['scale_uncertainty_ppm']:.0f} ppm)", err=True)
    if attrs.get("tuning_matches") is False:
        source = "chirp calibration" if attrs.get("chirp") else "G(I) table"
        marked = int(attrs.get("invalid_uncalibrated", 0))
        what = (f"; {marked} pairs marked uncalibrated: a chirp calibrated on a static target (fmcw-cl "
                "calibrate, then --chirp) gives them back at the usual precision" if marked
                else " (fmcw-cl calibrate)")
        if attrs.get("rest_calibration", "made") != "made":
            what += f" (not calibrated on its own rest: {attrs['rest_calibration']})"
        click.echo(f"warning: {cap}: its peaks are {attrs['tuning_peak_width_ratio']:.1f}x wider than the "
                   f"window's own: the laser's chirp does not match the {source}{what}", err=True)
    ratio = float(attrs.get("sync_period_ratio", 1.0))
    if abs(ratio - 1) > float(attrs.get("sync_period_warn", np.inf)):
        said = float(attrs["modulation_period_s"]) * 1e6
        click.echo(f"warning: {cap}: the sync repeats every {ratio * said:.3f} us of the sample clock, "
                   f"{100 * (ratio - 1):+.2f} % off the {said:.3f} us its sample_rate_hz and frequency_hz "
                   "attributes give: one of them is wrong (times and velocities scale with the sample rate); "
                   "correct the file's attribute", err=True)
    outside = attrs.get("echo_outside_band_m")
    if outside is not None:
        lo, top = attrs["min_range_m"], attrs["max_range_m"]
        band = f"{lo:.3f}-{top:.3f} m" if np.isfinite(top) else f"from {lo:.3f} m"
        click.echo(f"warning: {cap}: {100 * s['valid_share']:.1f} % valid in the band {band} "
                   f"(--min-range, --max-range): the strongest echo lies outside it, at {outside:.3f} m "
                   f"({attrs['echo_outside_band_db']:.0f} dB over the band's best); widen the band", err=True)
    if not s["valid_share"] and outside is None and attrs.get("tuning_matches", True):
        counts = {code: int(attrs.get(f"invalid_{name}", 0)) for code, name in faults.REASONS.items() if code}
        most = max(counts, key=counts.get)
        if counts[most]:
            click.echo(f"warning: {cap}: no valid pair; {counts[most]} of {s['pairs']} are "
                       f"{faults.REASONS[most]}: {faults.MEANINGS[most]}", err=True)
    target_lines(cap, attrs)
    rival = attrs.get("rival_echo_m")
    if rival is not None and np.isfinite(rival):
        db = float(attrs["rival_echo_db"])
        how = f"{abs(db):.1f} dB {'stronger' if db >= 0 else 'weaker'} than"
        what = (f"a moving echo (smeared by its Doppler shift) around {rival:.3f} m"
                if attrs.get("rival_echo_diffuse") else f"a fixed echo at {rival:.3f} m")
        click.echo(f"warning: {cap}: {what} is {how} the tracked target ({tracked(attrs)}) "
                   "(--target-near, --min-range, --max-range choose the target)", err=True)
    if quiet or as_json:
        return
    click.echo(f"{cap} -> {s['track']}\n  {s['duration_s']:.3f} s, {s['pairs']} pairs, "
               f"{100 * s['valid_share']:.1f} % valid, sync delay "
               f"{s['sync_delay_samples']:+.2f} samples, {s['device']}, "
               f"{s['processing_time_s']:.2f} s ({s['real_time_multiple']:.3g}x real time)")
    why = ", ".join(f"{n} {name}" for name, n in s["invalid"].items() if n)
    if why:
        click.echo(f"  invalid pairs: {why}")


def run_local(captures, outdir, options, stages, quiet, debug):
    """Yield {capture, track, attrs, valid} or {capture, error} per capture, in order.
    Captures convert as many at a time as the backend wants (batch.process_each); the
    bar shows the first one not yet reported."""
    captures = list(captures)
    bars: dict[int, Progress] = {}
    head = [0]
    shown = not quiet and sys.stderr.isatty()

    def progress(i: int, done: int, total: int, fs: float) -> None:
        if i not in bars:                       # made when its capture starts: its own rate
            bars[i] = Progress(f"[{i + 1}/{len(captures)}] {captures[i].name}", enabled=False)
        bars[i].enabled = shown and head[0] == i
        if total:
            bars[i](done, total, fs)

    for i, (cap, got) in enumerate(process_each(captures, options, stages, None, progress)):
        if i in bars:
            bars.pop(i).close()
        head[0] = i + 1
        out = track_path(outdir, cap)
        try:
            if isinstance(got, FmcwError):
                raise got
            write_track(out, got)
        except FmcwError as exc:
            if debug:
                raise
            yield {"capture": str(cap), "error": str(exc)}
            continue
        yield {"capture": str(cap), "track": str(out), "attrs": got.attrs, "valid": got.valid}


def run_cluster(captures, outdir, options, backend, device, scheduler, quiet):
    from fmcw_cl.cluster import connect, run_batch

    bar = Progress(f"dask {scheduler}", enabled=False if quiet else None)
    client = connect(scheduler)
    try:
        yield from run_batch(client, list(captures), outdir, options, backend, device, progress=bar)
    finally:
        bar.close()
        client.close()
        if scheduler.startswith("local:"):
            client.cluster.close()


@click.command("process")
@click.argument("captures", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--outdir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for the <capture stem>.track.h5 files.")
@opts.click_options(opts.PROCESS + opts.RUN)
@click.option("--skip-existing", is_flag=True, help="Leave captures whose track exists.")
@click.option("--scheduler", default=None,
              help="Run on a Dask cluster: a scheduler address (tcp://host:8786), or local:N for N "
                   "worker processes here. Paths must be valid on the workers.")
@click.option("--json", "as_json", is_flag=True,
              help="Print one record per capture as JSON on stdout: its summary, or its error, or why "
                   "it was skipped.")
@click.option("-q", "--quiet", is_flag=True, help="No progress, no summary.")
@click.pass_context
def command(ctx, captures, outdir, skip_existing, scheduler, as_json, quiet, **options):
    """Convert CAPTURE files into tracks (distance, velocity, acceleration).

    \b
    Example:
      fmcw-cl process data_samples/static_0p3m.h5 -o tracks/
      fmcw-cl process runs/*.h5 -o tracks/ --scheduler local:2
      fmcw-cl process wall.h5 -o tracks/ --max-range 0.40
    """
    options, backend, device = opts.from_keywords(options)     # every check before any work
    output_folder(outdir)
    existing = [c for c in captures if track_path(outdir, c).exists()]
    skip = set(existing) if skip_existing else set()
    todo = [c for c in captures if c not in skip]
    results: list[dict] = []
    if existing and not quiet:
        what = "skipping" if skip_existing else "overwriting"
        click.echo(f"note: {what} {len(existing)} existing track{'s' if len(existing) > 1 else ''} in "
                   f"{outdir} ({_names(existing)})", err=True)
    if skip_existing:
        results += [{"capture": str(c), "skipped": "its track exists"} for c in existing]
    if scheduler:
        runs = run_cluster(todo, outdir, options, backend, device, scheduler, quiet)
    else:
        stages = make_processor(backend, device, warn=lambda m: click.echo(m, err=True))
        runs = run_local(todo, outdir, options, stages, quiet, ctx.obj.get("debug"))
    failed = 0
    for got in runs:
        if "error" in got:
            click.echo(f"error: {got['error']}", err=True)
            results.append(got)
            failed += 1
            continue
        s = summary(got["capture"], got["track"], got["attrs"], got["valid"])
        results.append(s)
        report(s, got["attrs"], quiet, as_json)
    if as_json:
        click.echo(json.dumps(results, indent=2))
    skipped = len(captures) - len(todo)
    if not quiet and (len(captures) > 1 or skipped):      # one capture: its own line says it
        empty = sum(1 for r in results if r.get("valid_share") == 0)
        none = f" ({empty} with no valid pair)" if empty else ""
        click.echo(f"{len(captures)} capture{'s' if len(captures) > 1 else ''}: {len(todo) - failed} "
                   f"converted{none}, {failed} failed, {skipped} skipped", err=True)
    if failed:
        sys.exit(1)


def _names(paths, most: int = 3) -> str:
    """The first `most` file names, and how many more."""
    names = ", ".join(p.name for p in paths[:most])
    return names + (f" and {len(paths) - most} more" if len(paths) > most else "")
