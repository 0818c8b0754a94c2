"""`fmcw-cl info`: what a capture holds."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from fmcw_cl.capture import Capture
from fmcw_cl.errors import FmcwError
from fmcw_cl.options import Options
from fmcw_cl.plan import Plan, make_plan
from fmcw_cl.stages import faults
from fmcw_cl.stages.delay import CLEAN_MISFIT
from fmcw_cl.stages.lut import build_lut


def delay_line(plan: Plan) -> str:
    """The sync delay as `process` uses it: refined on the target with its uncertainty,
    and the intensity triangle's first estimate."""
    first = (f"the intensity triangle gave {plan.lag_intensity:+.3f} ({plan.lag_periods} periods, misfit "
             f"{plan.lag_misfit:.3f}{'' if plan.lag_misfit <= CLEAN_MISFIT else ', UNRELIABLE'})")
    if not plan.lag_refined:
        return (f"sync lags the optics by {plan.lag:+.3f} samples: {first}; no valid run of a target to "
                "refine it on")
    return (f"sync lags the optics by {plan.lag:+.3f} +-{plan.lag_sigma_samples:.3f} samples, refined on the "
            f"target (velocities +-{plan.lag_sigma_mps:.4f} m/s, distances +-{1e3 * plan.lag_sigma_m:.4f} mm "
            f"at {plan.lag_at_m:.3f} m); {first}")


@click.command("info")
@click.argument("capture", type=click.Path(path_type=Path))
@click.option("--points", default=1000, show_default=True,
              help="Resampling intervals, for the unambiguous range.")
@click.option("--delay/--no-delay", default=True, show_default=True,
              help="Estimate the sync delay as `process` does (printed last: it converts stretches of "
                   "the capture).")
def command(capture, points, delay):
    """Describe CAPTURE: duration, periods, sweep bandwidth, ranges, sync delay, levels.

    \b
    Example:
      fmcw-cl info data_samples/static_0p3m.h5
      fmcw-cl info run7.h5 --no-delay
    """
    with Capture(capture) as cap:
        i = cap.info
        m = i.modulation
        lut = build_lut(i.tuning_current_a, i.tuning_frequency_hz, m.current_min_a,
                        m.current_max_a, points, i.refractive_index)
        beat, _ = cap.read(0, min(i.samples, int(20 * i.samples_per_period)))
        clipped = int(np.sum(faults.is_clipped(beat, i.full_scale + 1)))
        lines = [
            f"capture        {capture}",
            f"samples        {i.samples} per channel at {i.sample_rate_hz / 1e6:g} MS/s, "
            f"{i.bits} bits",
            f"duration       {i.duration_s:.6f} s, {i.periods:.1f} modulation periods",
            f"modulation     {m.waveform} {m.frequency_hz / 1e3:g} kHz, "
            f"{m.current_min_a * 1e3:g}-{m.current_max_a * 1e3:g} mA",
            f"G(I) table     {i.tuning_current_a.size} points, "
            f"{i.tuning_current_a[0] * 1e3:g}-{i.tuning_current_a[-1] * 1e3:g} mA",
            f"sweep          {lut.bandwidth_hz / 1e9:.3f} GHz, range resolution "
            f"{lut.range_resolution_m * 1e3:.3f} mm, n = {i.refractive_index:g}",
            (f"distance scale +-{lut.scale_ppm:.0f} ppm (1 sigma) from the G(I) fit's errors, shape included "
             f"({lut.table_scatter_hz / 1e6:.1f} MHz rms about a degree-{lut.fit_degree} fit): "
             f"+-{lut.scale_ppm * 1e-3 * 0.3:.3f} mm at 0.3 m, "
             f"+-{lut.scale_ppm * 1e-3 * lut.unambiguous_range_m:.3f} mm at the range's end; "
             "calibrate (fmcw-cl calibrate) where that is too much") if np.isfinite(lut.scale_ppm) else
            (f"distance scale unknown: {i.tuning_current_a.size} G(I) points about a degree-{lut.fit_degree} "
             "fit leave under 3 degrees of freedom to judge its errors; calibrate (fmcw-cl calibrate)"),
            f"unambiguous    {lut.unambiguous_range_m:.4f} m at --points {points}",
            f"beat level     rms {beat.std():.0f} codes, peak {np.abs(beat.astype(np.int32)).max()} of "
            f"{i.full_scale + 1}, {clipped} codes at full scale ({100 * clipped / max(beat.size, 1):.3f} %) "
            f"in the first 20 periods (a pair is flagged clipped from {100 * faults.CLIP_SHARE:g} % of "
            "its span)",
            f"truth          {'yes' if i.has_truth else 'no'}",
        ]
        click.echo("\n".join(lines))          # at once: the delay converts stretches of the capture
        if not delay:
            return
        try:                          # what `process` refuses is said, not estimated
            said = delay_line(make_plan(cap, Options(points=points)))
        except FmcwError as exc:
            said = f"none: {getattr(exc, 'problem', exc)} (process refuses this capture)"
        click.echo(f"sync delay     {said}")
