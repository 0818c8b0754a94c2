"""The capture's uncertainty budget as a GUM table (uncertainty.md): per quantity, each
source's standard uncertainty (rms over the valid pairs) and its share of the combined
variance, the expanded uncertainty (k = 2); against the capture's truth where it has
one, the share of valid pairs within their own expanded uncertainty."""

from __future__ import annotations

import numpy as np

from ..capture_format import Truth
from ..evaluate import truth_at
from ..track import Track
from ..uncertainty import budget_from_attrs

QUANTITIES = (("distance", "distance_m", "distance_uncertainty_m", "valid", 1e6, "µm"),
              ("velocity", "velocity_mps", "velocity_uncertainty_mps", "velocity_valid", 1e3, "mm/s"),
              ("acceleration", "acceleration_mps2", "acceleration_uncertainty_mps2", "acceleration_valid",
               1.0, "m/s²"))


def coverage(track: Track, truth: Truth) -> dict[str, tuple[int, float, float]]:
    """Per quantity: (pairs checked, share within their expanded uncertainty, median
    uncertainty over the rms error) against `truth`."""
    out = {}
    true = dict(zip(("distance_m", "velocity_mps", "acceleration_mps2"), truth_at(truth, track.time_s),
                    strict=True))
    for name, value, unc, flag, _, _ in QUANTITIES:
        ok = getattr(track, flag)
        u = getattr(track, unc)
        if u is None or not ok.any():
            continue
        err = np.abs(getattr(track, value)[ok] - true[value][ok])
        rms = float(np.sqrt(np.mean(err**2)))
        out[name] = (int(ok.sum()), float(np.mean(err <= u[ok])),
                     float(np.median(u[ok])) / rms if rms > 0 else float("inf"))
    return out


def budget_markdown(track: Track, title: str, truth: Truth | None = None) -> str:
    """uncertainty.md: the budgets (`uncertainty.budget_from_attrs`), then the check
    against the truth."""
    k = float(track.attrs.get("uncertainty_coverage_factor", 2.0))
    lines = [f"# Uncertainty budget: {title}", ""]
    for name, _, unc, flag, scale, unit in QUANTITIES:
        rows = budget_from_attrs(track.attrs, name)
        u = getattr(track, unc)
        ok = getattr(track, flag)
        if name == "acceleration" and u is not None and ok.any():
            lines += [f"Acceleration ({int(ok.sum())} pairs): expanded uncertainty (k = {k:g}) median "
                      f"{np.median(u[ok]):.3g} m/s², 95th percentile {np.percentile(u[ok], 95):.3g} m/s² "
                      "(the velocities' noise through the derivative, and the smoothing's bias where the "
                      "acceleration bends; `/track/acceleration_uncertainty_mps2`).", ""]
            continue
        if not rows or u is None or not ok.any():
            lines += [f"{name.capitalize()}: no valid pair, no budget.", ""]
            continue
        lines += [f"## {name.capitalize()} ({int(ok.sum())} pairs)", "",
                  f"| source | standard uncertainty ({unit}, rms) | share of the variance |",
                  "|---|---:|---:|"]
        for src, rms, share in rows[:-1]:
            lines.append(f"| {src} | {scale * rms:.3g} | {100 * share:.1f} % |")
        lines += [f"| combined | {scale * rows[-1][1]:.3g} | 100 % |", "",
                  f"Expanded uncertainty (k = {k:g}) per pair: median {scale * np.median(u[ok]):.3g} {unit}, "
                  f"95th percentile {scale * np.percentile(u[ok], 95):.3g} {unit} "
                  f"(`/track/{unc}`).", ""]
    if truth is not None:
        got = coverage(track, truth)
        if got:
            lines += ["## Against the capture's truth", "",
                      "| quantity | pairs | within their expanded uncertainty | median uncertainty / rms "
                      "error |", "|---|---:|---:|---:|"]
            lines += [f"| {name} | {n} | {100 * share:.1f} % | {sharp:.2f} |"
                      for name, (n, share, sharp) in got.items()]
            lines.append("")
    return "\n".join(lines)
