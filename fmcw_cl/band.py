"""Whether the band the user set leaves the target out: the strongest echo of the whole
spectrum, where a conversion found next to nothing inside --min-range/--max-range.

A lone static target at 0.3 m converted with --max-range 0.2 gives 0 % valid pairs, every
one `no_echo`; the cause is the range gate, and the user is told where the echo is. The
mean of the plain power spectra of BAND_PERIODS periods from the middle of the capture
(each direction apart) is searched from the default --min-range to the unambiguous range.
"""

from __future__ import annotations

import numpy as np

from .capture import Capture
from .options import Options
from .stages import resample, sync

BAND_PERIODS = 100
OUTSIDE_DB = 10.0        # the echo outside stands this far over the best inside, and over the noise


def echo_outside(cap: Capture, plan, backend) -> tuple[float, float] | None:
    """(distance m, dB over the band's strongest) of the strongest echo outside the
    plan's band, where it stands OUTSIDE_DB over the band's best and over the spectrum's
    median (the noise); None where the band holds the strongest, or no echo stands out.
    `backend`: the stages'."""
    info = cap.info
    spp = info.samples_per_period
    a = max(0, info.samples // 2 - int(BAND_PERIODS / 2 * spp))
    beat, sy = cap.read(a, min(info.samples, a + int((BAND_PERIODS + 2) * spp)))
    hs = sync.half_sweeps(backend.turning_points(sy, spp / 2), plan.lag)
    fits = resample.inside(hs.start, hs.length, plan.lut, beat.size)
    sels = [fits & (hs.rising == rising) for rising in (True, False)]
    if not all(s.any() for s in sels):
        return None
    rows = backend.resample_each(beat, [(hs.start[s], hs.length[s], plan.lut.u(up))
                                        for s, up in zip(sels, (True, False), strict=True)], plan.window)
    nfft = plan.model.nfft
    mean = sum(p.mean(axis=0) for p in backend.power_each([(x, None, None) for x in rows], nfft))
    m = plan.model.metres_per_bin
    lo = max(1, int(np.ceil(Options.min_range / m)))       # the default gate: DC, ramp and lens below
    inside = np.zeros(mean.size, bool)
    inside[plan.search.lo: plan.search.hi] = True
    outside = ~inside & (np.arange(mean.size) >= lo)
    if not outside.any():
        return None
    k = int(np.flatnonzero(outside)[np.argmax(mean[outside])])
    best_in = float(mean[inside].max(initial=0.0))
    over = 10 * np.log10(mean[k] / max(best_in, np.finfo(float).tiny))
    noise = float(np.median(mean[lo:]))
    if over < OUTSIDE_DB or 10 * np.log10(mean[k] / noise) < OUTSIDE_DB:
        return None
    return float(k * m), float(over)
