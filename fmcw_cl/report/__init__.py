"""A track's report: pictures of the paper's figures and its event table.

`make_report` writes, into one folder (each file atomically):
kinematics.png, echoes.png (every echo over range and time, when the track lists
them), spectra.png (when the source capture is readable), precision.png (static
targets only), displacement.png (the displacement from the phase and its amplitude
spectrum, where it holds), events.md and events.json, uncertainty.md (the GUM budget).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..atomic import atomic_path, output_folder
from ..capture import Capture
from ..capture_format import Truth
from ..errors import CaptureError
from ..evaluate import truth_at
from ..track import Track, read_track
from .budget import budget_markdown
from .events import WINDOW_PAIRS, Event, compare, find_events, left_out, verified_stretches

STATIC_MPS = 0.01        # a track is "static" when 95 % of its |velocity| is below this
SLOW_MPS = 0.2           # spectra are shown where the target is this slow (no Doppler smear)
SPECTRA_SPAN_S = 0.01    # stretch of spectra shown
TRUTH_GRID_S = 1e-6      # the true events are found on this grid

UNITS = {"distance_m": "m", "velocity_mps": "m/s", "acceleration_mps2": "m/s²"}


def is_static(track: Track) -> bool:
    v = track.velocity_mps[track.velocity_valid]
    return v.size > 10 and float(np.percentile(np.abs(v), 95)) < STATIC_MPS


def true_events(truth: Truth, t0: float, t1: float, edge_s: float) -> list[Event]:
    """Events of the true trajectory between t0 and t1 (s), on a fine grid: its own
    extrema, none within `edge_s` of the span's ends (as for the track)."""
    g = np.arange(max(t0, truth.time_s[0]), min(t1, truth.time_s[-1]), TRUTH_GRID_S)
    return find_events(g, *truth_at(truth, g), refine_s=20 * TRUTH_GRID_S, edge_s=edge_s)


def events_markdown(rows: list[dict], title: str, skipped: dict | None = None, at_rest: bool = False,
                    who: str = "the target") -> str:
    """The event table as Markdown (times in ms; errors when a truth was matched; what
    was left out, `events.left_out`, under it); with no event, `at_rest` says why."""
    truth = any(r["true_time_s"] is not None for r in rows)
    head = "| event | time (ms) | value | unit |"
    rule = "|---|---:|---:|---|"
    if truth:
        head += " true time (ms) | true value | time error (ms) | value error (%) |"
        rule += "---:|---:|---:|---:|"
    lines = [f"# Events: {title}", "", head, rule]
    for r in rows:
        kind = r["kind"].replace("_", " ")
        line = (f"| {kind} | {1e3 * r['time_s']:.3f} | {r['value']:.4g} | "
                f"{UNITS[r['quantity']]} |")
        if truth:
            if r["true_time_s"] is None:
                line += " – | – | – | – |"
            else:
                rel = r["value_error_rel"]
                line += (f" {1e3 * r['true_time_s']:.3f} | {r['true_value']:.4g} | "
                         f"{1e3 * r['time_error_s']:+.3f} | "
                         f"{'–' if rel is None else f'{100 * rel:+.2f}'} |")
        lines.append(line)
    if not rows:
        lines.append(f"| (none: {who} is at rest) | | | |" if at_rest else
                     "| (none: no extremum inside the verified stretches) | | | |")
    if skipped:
        k = skipped
        lines += ["", f"Events are taken from runs of at least {k['min_stretch_pairs']} valid pairs only: of "
                      f"{k['pairs']} pairs, {k['invalid']} invalid and {k['short_stretches']} valid ones in "
                      "shorter runs were left out."]
    return "\n".join(lines) + "\n"


def _events_of(t: Track, edge_s: float) -> tuple[list, dict, bool]:
    """A track's events from its verified stretches, what was left out, and whether it is
    at rest (what the verified velocities say, not the want of an event)."""
    used = verified_stretches(t.valid)
    # each quantity where it is valid itself: a verified distance may carry a velocity
    # or an acceleration that is not
    series = ((t.distance_m, used), (t.velocity_mps, used & t.velocity_valid),
              (t.acceleration_mps2, used & t.acceleration_valid))
    ev = find_events(t.time_s, *[np.where(ok, x, np.nan) for x, ok in series], edge_s=edge_s)
    moving = used & t.velocity_valid
    at_rest = bool(moving.any() and np.percentile(np.abs(t.velocity_mps[moving]), 95) < STATIC_MPS)
    return ev, left_out(t.valid, used), at_rest


def _object_events(o, edge_s: float) -> tuple:
    """An object's events (no truth: the capture's is the target's): (object, rows,
    what was left out, at rest)."""
    ev, skipped, at_rest = _events_of(o.track, edge_s)
    return o, compare(ev, []), skipped, at_rest


def _write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _source(track: Track, capture: str | os.PathLike | None) -> tuple[Path | None, str]:
    """The source capture, or None and why it is not at hand."""
    if capture is not None:
        if not Path(capture).is_file():
            raise CaptureError(Path(capture), "no such capture file (--capture)")
        return Path(capture), ""
    src = track.attrs.get("source")
    if not src:
        return None, "the track names no source capture: give it with --capture"
    if not Path(src).is_file():
        return None, f"its capture {src} is not there (moved?): give it with --capture"
    return Path(src), ""


def make_report(track_file: str | os.PathLike, outdir: str | os.PathLike,
                capture: str | os.PathLike | None = None, at_s: float | None = None,
                span_s: float = SPECTRA_SPAN_S) -> dict:
    """Write the report of one track; returns what was written (`written`), the event
    rows (`events`) and what was left out and why (`left_out`).

    Parameters
    ----------
    track_file : a track written by `fmcw-cl process`.
    outdir : folder for the report (created).
    capture : the source capture (default: the track's ``source`` attribute); without
        it there is no truth overlay and no spectra (`left_out` says why).
    at_s : centre (s) of the spectra's stretch; default: the farthest moment where the
        target is slow (the nonlinearity smears far targets most, Doppler none).
    span_s : length (s) of the spectra's stretch.
    """
    from . import figures  # matplotlib only when a report is made
    from .spectra import stretch_spectra

    try:
        track = read_track(track_file)
    except (OSError, ValueError, KeyError) as exc:
        raise CaptureError(Path(track_file), f"not a readable track file ({exc})") from None
    out = output_folder(outdir)
    src, missing = _source(track, capture)
    truth = None
    if src is not None:
        with Capture(src) as cap:
            truth = cap.truth()
    written: list[Path] = []
    edge_s = (WINDOW_PAIRS // 2) * float(track.attrs.get("modulation_period_s", 5e-5))
    ev, skipped, at_rest = _events_of(track, edge_s)
    t0, t1 = (float(track.time_s[0]), float(track.time_s[-1])) if track.pairs else (0.0, 0.0)
    rows = compare(ev, true_events(truth, t0, t1, edge_s) if truth is not None else [])

    with atomic_path(out / "kinematics.png") as tmp:
        figures.kinematics(track, tmp, truth, ev)
    written.append(out / "kinematics.png")
    if track.echoes is not None:
        with atomic_path(out / "echoes.png") as tmp:
            figures.echoes(track, tmp)
        written.append(out / "echoes.png")
    if src is not None and track.pairs:
        if at_s is None:
            slow = track.valid & (np.abs(np.nan_to_num(track.velocity_mps, nan=np.inf)) < SLOW_MPS)
            at_s = (float(track.time_s[slow][np.argmax(track.distance_m[slow])]) if slow.any()
                    else 0.5 * (t0 + t1))
        sp = stretch_spectra(src, at_s - span_s / 2, at_s + span_s / 2, int(track.attrs["points"]),
                             float(track.attrs["sync_delay_samples"]), float(track.attrs["min_range_m"]),
                             track.chirp)
        chosen = int(np.argmin(np.abs(sp.time_s - at_s)))
        with atomic_path(out / "spectra.png") as tmp:
            figures.spectra(sp, tmp, chosen, float(track.attrs["unambiguous_range_m"]),
                            float(track.attrs["min_range_m"]))
        written.append(out / "spectra.png")
    if is_static(track):
        true_d = float(np.median(truth.distance_m)) if truth is not None else None
        with atomic_path(out / "precision.png") as tmp:
            figures.precision(track, tmp, true_d)
        written.append(out / "precision.png")
    if track.displacement_valid is not None and track.displacement_valid.any():
        with atomic_path(out / "displacement.png") as tmp:
            figures.displacement(track, tmp, truth)
        written.append(out / "displacement.png")
    title = Path(str(track.attrs.get("source", track_file))).name
    others = [_object_events(o, edge_s) for o in track.objects or []
              if o.id != track.attrs.get("target_object")]
    text = events_markdown(rows, title if not others else f"{title}: the target, object "
                           f"#{track.attrs['target_object']}", skipped, at_rest)
    text += "".join("\n" + events_markdown(r, f"{title}: object #{o.id} ({o.kind})", s, a, "the object")
                    for o, r, s, a in others)
    _write_text(out / "events.md", text)
    _write_text(out / "events.json", json.dumps(
        {"track": str(track_file), "source": str(src) if src else None, "events": rows, "left_out": skipped,
         "objects": [{"object": o.id, "kind": o.kind, "events": r, "left_out": s} for o, r, s, _ in others]},
        indent=2))
    _write_text(out / "uncertainty.md", budget_markdown(track, title, truth))
    written += [out / "events.md", out / "events.json", out / "uncertainty.md"]
    left = {} if not missing or not track.pairs else {"spectra.png and the truth": missing}
    return {"written": [str(p) for p in written], "events": rows, "left_out": left}


__all__ = ["make_report", "find_events", "compare", "Event", "is_static"]
