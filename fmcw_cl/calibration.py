"""The real chirp, measured from a capture of a static target at a known distance.

A DFB under 20 kHz modulation does not follow its static G(I): the thermal part of the
tuning lags the current, so the sweep is narrower, rising and falling differ, and the
optical turning points come late. As swept-source OCT does with a reference arm, the
beat of a known delay tau = 2 R n / c gives the optical frequency: its phase is
2 pi tau nu(t). The beat is band-passed around the target's beat frequencies (found
from G(I), with room) as an analytic signal, and each half-sweep of the sync (the
pipeline's own segmentation) sampled on a grid of its time fraction s.

A lab's calibration target is diffuse: about 0 dB per sample, and noise that makes
single sweeps' phases slip cycles. So the sweeps of a direction are averaged *before*
the phase is unwrapped: each is de-chirped by the static G(I) (the target's beat then
varies slowly along s), its unknown phase constant aligned to the mean, and the
complex mean taken: K periods gain 10 log10 K dB (33 dB for 2000). In that mean the
target varies within CUTOFF tau B cycles per half-sweep (a lagging laser's chirp
departs from G(I) by less); another static echo (a wall) beats (tau' - tau) B cycles
away and is cut off (`isolate`) before the phase is taken: an echo farther than
(1 + CUTOFF) R, or nearer than (1 - CUTOFF) R, is isolated. The low-pass also dims the
sweep's ends, where the real chirp departs most from G(I) (a narrower calibrated band),
so it is applied only where it removes OTHER_ECHO of the core's energy: another echo.
The phase of the mean, re-chirped, divided by 2 pi tau, is the optical frequency.
Where the beat frequency nears 0 Hz (the optical turning points) the phase is
unusable, so each direction keeps the stretch where the chirp is steep. A capture
whose mean is still too noisy (phase noise above MAX_PHASE_RAD) is refused, naming
its measured SNR.
"""

from __future__ import annotations

import contextlib

import numpy as np

from . import __version__
from .capture import Capture
from .chirp import Chirp, Direction
from .errors import CaptureError
from .options import Options
from .physics import C
from .plan import make_plan
from .processor import ChunkProcessor, NumpyProcessor
from .stages import doppler, resample, sync
from .stages.lut import fit_tuning

GRID = 2048              # points of the s grid over [S_LO, S_HI]
S_LO, S_HI = -0.2, 1.2   # the optics may lag the sync: look past the sync's turning points
STEEP = 0.35             # keep s where the chirp is at least this share of its median slope
MAX_PHASE_RAD = 0.05     # rms phase noise of the averaged sweep allowed in the kept stretch
CUTOFF = 0.3             # isolation low-pass, as a share of the target's tau B (cycles per half-sweep)
OTHER_ECHO = 0.3         # isolate where the low-pass removes this share of the core's energy (a lag: < 0.2)


def _analytic(x: np.ndarray, fs: float, f_lo: float, f_hi: float) -> np.ndarray:
    """Analytic signal of x restricted to [f_lo, f_hi] (Hz)."""
    import scipy.fft  # here: a conversion that calibrates nothing imports no scipy

    n = x.size
    spec = scipy.fft.fft(x - x.mean(), workers=-1)
    f = scipy.fft.fftfreq(n, 1 / fs)
    spec[(f < f_lo) | (f > f_hi)] = 0
    return scipy.fft.ifft(2 * spec, workers=-1)


def measure_chirp(path, distance_m: float, periods: int = 2000, processor: ChunkProcessor | None = None
                  ) -> Chirp:
    """Calibrate the chirp from `periods` periods in the middle of a static capture.

    Parameters
    ----------
    path : capture of a static target.
    distance_m : its distance R (m); sets the frequency scale through tau = 2 R n / c.
    periods : modulation periods averaged.
    processor : runs the sync delay's estimate and trial conversions (`make_plan`;
        default numpy); closed when done.
    """
    with Capture(path) as cap, contextlib.closing(processor or NumpyProcessor()) as processor:
        info = cap.info
        plan = make_plan(cap, Options(range_check=False), processor=processor)   # its LUT and delay only
        spp = info.samples_per_period
        n = int(min(info.samples, periods * spp + 4 * spp))
        a = max(0, (info.samples - n) // 2)
        return chirp_of(cap, plan, distance_m, a, a + n)


def chirp_of(cap: Capture, plan, distance_m: float, start: int, stop: int) -> Chirp:
    """The chirp measured on samples [start, stop) of `cap`, where a static target
    stands at `distance_m` (m); `plan` (a static G(I) table's) gives the half-sweeps'
    delay and the beat frequencies to expect."""
    info = cap.info
    spp = info.samples_per_period
    beat, sy = cap.read(start, stop)
    fs, nidx = info.sample_rate_hz, info.refractive_index
    tau = 2 * distance_m * nidx / C
    if not 0.02 < distance_m < 0.9 * plan.lut.unambiguous_range_m * 4:
        raise CaptureError(info.path, f"--distance {distance_m:g} m is implausible for this capture")
    # beat frequencies the static G(I) predicts, with room for a narrower real sweep
    half_s = info.modulation.period_s / 2
    rate = plan.lut.bandwidth_hz / half_s
    f_lo, f_hi = 0.15 * tau * rate, min(0.49 * fs, 4.0 * tau * rate)
    z = _analytic(beat.astype(np.float64), fs, f_lo, f_hi)
    hs = sync.half_sweeps(sync.sync_turning_points(sy, spp / 2), plan.lag)
    grid = np.linspace(S_LO, S_HI, GRID)
    g = fit_tuning(info.tuning_current_a, info.tuning_frequency_hz)
    m = info.modulation
    in_band = 2 * (f_hi - f_lo) / fs            # share of the noise the analytic band keeps
    dirs, residual, counts, snrs, isolated = [], [], [], [], False
    for rising in (True, False):
        sel = ((hs.rising == rising) & (hs.start + S_LO * hs.length >= 0)
               & (hs.start + S_HI * hs.length < z.size - 2))
        if sel.sum() < 10:
            raise CaptureError(info.path, "too few half-sweeps to calibrate (is the sync a triangle?)")
        pos = hs.start[sel, None] + grid[None, :] * hs.length[sel, None]
        i = np.floor(pos).astype(np.int64)
        rows = z[i] + (z[i + 1] - z[i]) * (pos - i)
        # the static G(I) along s, the current's ramp continued past the turning points: a
        # folded reference would put a kink where the lagging optics still sweep
        x = grid if rising else 1 - grid
        nu_static = g(m.current_min_a + (m.current_max_a - m.current_min_a) * x)
        core = (grid > 0.35) & (grid < 0.65)
        sense = np.sign(np.median(np.gradient(nu_static)[core]))    # the analytic phase rises
        ref_phase = sense * 2 * np.pi * tau * (nu_static - nu_static[GRID // 2])
        d = rows * np.exp(-1j * ref_phase)
        mean = d[0]
        for _ in range(3):                       # align every sweep's phase constant to the mean
            turn = np.exp(-1j * np.angle(d[:, core] @ np.conj(mean[core])))
            mean = np.mean(d * turn[:, None], axis=0)
        aligned = d * turn[:, None]
        target = isolate(mean, CUTOFF * tau * plan.lut.bandwidth_hz)
        other = 1 - np.sum(np.abs(target[core]) ** 2) / np.sum(np.abs(mean[core]) ** 2) >= OTHER_ECHO
        isolated |= bool(other)
        if not other:
            target = mean          # no other echo to cut: keep the whole sweep's band
        noise = np.mean(np.abs(aligned[:, core] - mean[core]) ** 2)
        snr_sample = float(np.mean(np.abs(target[core]) ** 2) / noise * in_band)
        snrs.append(10 * np.log10(max(snr_sample, 1e-30)))
        nu = sense * (np.unwrap(np.angle(target)) + ref_phase) / (2 * np.pi * tau)
        level = np.abs(target)
        nu[level < 0.3 * np.median(level[core])] = np.nan
        keep = _steep_stretch(grid, nu - np.nanmean(nu[core]))
        phase_noise = float(np.sqrt(noise / (2 * sel.sum() * np.mean(level[keep] ** 2))))
        if not phase_noise <= MAX_PHASE_RAD:
            raise CaptureError(info.path, f"too noisy to calibrate: the target's SNR is {snrs[-1]:.1f} dB "
                                          f"per sample, and {int(sel.sum())} periods leave {phase_noise:.3f} "
                                          f"rad of phase noise (at most {MAX_PHASE_RAD}): record more "
                                          "periods (--periods), or a brighter target")
        residual.append(float(np.sqrt(np.mean(np.angle(aligned[:, keep] * np.conj(target[keep])) ** 2))))
        counts.append(int(sel.sum()))
        dirs.append(Direction(grid[keep], nu[keep] - np.mean(nu[keep & core])))   # optical frequency, Hz
    chirp = Chirp(*dirs)
    attrs = {
        "distance_m": float(distance_m), "refractive_index": nidx,
        "periods_used": int(min(counts)),
        "residual_phase_rad": float(max(residual)),
        "snr_db_per_sample": float(min(snrs)),
        "other_echo_isolated": bool(isolated),
        "bandwidth_rising_hz": dirs[0].bandwidth_hz, "bandwidth_falling_hz": dirs[1].bandwidth_hz,
        "bandwidth_hz": chirp.bandwidth_hz, "static_bandwidth_hz": plan.lut.bandwidth_hz,
        "table_distance_m": table_distance(beat, hs, plan),
        "sync_delay_samples": float(plan.lag), "modulation_frequency_hz": info.modulation.frequency_hz,
        "sample_rate_hz": fs, "source": str(info.path), "software": f"fmcw-cl {__version__}",
    }
    return Chirp(chirp.rising, chirp.falling, attrs)


def table_distance(beat: np.ndarray, hs, plan, sweeps: int = 200) -> float:
    """The static target's distance (m) by the capture's own G(I) table: the median of
    the plain peaks of up to `sweeps` half-sweeps of each direction (no Doppler at rest).
    A chirp calibration corrects the table's scale by a few percent; a --distance far
    from this one is more likely wrong than the table (`fmcw-cl calibrate` says so)."""
    got = []
    for rising in (True, False):
        ok = (hs.rising == rising) & resample.inside(hs.start, hs.length, plan.lut, beat.size)
        idx = np.flatnonzero(ok)[:sweeps]
        if idx.size:
            x = resample.resample(beat, hs.start[idx], hs.length[idx], plan.lut.u(rising), plan.window)
            got.append(doppler.measure(x, None, None, plan.model, plan.search)[0])
    return float(np.median(np.concatenate(got))) if got else float("nan")


def isolate(mean: np.ndarray, cutoff_cycles: float) -> np.ndarray:
    """The target's component of a de-chirped mean sweep: a low-pass along s (super-
    Gaussian, -3 dB at `cutoff_cycles` per half-sweep). The target's own residual
    (its real chirp against the static G(I)) stays below it; another static echo's
    beat is (tau' - tau) B cycles per half-sweep away and is cut."""
    n = mean.size
    cycles = np.fft.fftfreq(n, (S_HI - S_LO) / n)       # per half-sweep
    response = 2.0 ** (-((cycles / cutoff_cycles) ** 8))
    return np.fft.ifft(np.fft.fft(mean) * response)


def _steep_stretch(grid: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Mask of the contiguous stretch around s = 0.5 where nu is measured and steep."""
    slope = np.abs(np.gradient(nu, grid))
    ok = np.isfinite(slope) & (slope >= STEEP * np.nanmedian(slope[(grid > 0.2) & (grid < 0.8)]))
    mid = int(np.argmin(np.abs(grid - 0.5)))
    lo = mid
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    hi = mid
    while hi < grid.size - 1 and ok[hi + 1]:
        hi += 1
    keep = np.zeros(grid.size, bool)
    keep[lo:hi + 1] = True
    return keep
