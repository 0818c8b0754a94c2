"""Synthesise a two-channel capture (beat, sync) chunk by chunk into a capture file.

The beat phase comes from the optical phase, phi = 2 pi [nu(t) tau - nu'(t) tau^2 / 2]
with tau = 2 R(t) n / c, so a moving target gets its Doppler shift from the physics;
laser phase noise enters as the difference of one random-walk phase at t and t - tau.
A real scene adds static reflectors (a wall, a window), other moving echoes (a second
limb, a hand in the beam), stretches where an echo is hidden (an occlusion; the truth
of every echo is written with where it can be seen), speckle fading of the
target's echo (a complex Gaussian field, Rayleigh amplitude), relative intensity
noise of the laser and white detector noise set by a per-sample SNR
(docs/pipeline.md, "The simulator").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..capture_format import Modulation, Truth
from ..capture_writer import CaptureWriter
from ..physics import C
from .laser import DfbLaser, paper_dfb
from .scene import Trajectory

CHUNK = 1 << 20
TRUTH_STEP_S = 10e-6
HISTORY = 64  # phase-noise history kept across chunks (supports tau < 64 samples: 96 m)
SNR_REF_M = 0.3      # --snr-db is the target's SNR at this distance
SPECKLE_GRID = 40    # points per correlation time of the tabulated speckle field
HEADROOM = 6.0       # a lab sets the detector gain so that the noise's rms stays this far below full scale


EDGE_S = 50e-6       # an occluding edge crosses the beam in this time


@dataclass(frozen=True)
class Mover:
    """Another moving echo: its trajectory, amplitude (codes at 320 mA) and the
    stretches (start, end s) where it is hidden (or out of the beam)."""

    trajectory: Trajectory
    amplitude_codes: float
    hidden: tuple[tuple[float, float], ...] = ()


def visibility(t: np.ndarray, hidden: tuple[tuple[float, float], ...]) -> np.ndarray:
    """The share (0-1) of an echo seen at times `t` (s), hidden over the `hidden`
    stretches, each edge a linear ramp of EDGE_S."""
    seen = np.ones_like(t)
    for a, b in hidden:
        inside = np.clip(np.minimum(t - a, b - t) / EDGE_S + 0.5, 0.0, 1.0)
        seen = np.minimum(seen, 1.0 - inside)
    return seen


@dataclass(frozen=True)
class SimulationConfig:
    """Instrument parameters of a simulated capture (defaults: the paper's set-up).

    ADC levels are in codes of a `bits`-bit converter. `sync_delay_samples` is how far
    the sync channel lags the optics (negative: it leads); None draws it from the seed
    in [-40, 40]. `start_phase` is the modulation phase at sample 0 (None: from the seed).
    """

    sample_rate_hz: float = 100e6
    bits: int = 14
    modulation: Modulation = Modulation(20e3, 0.160, 0.480)
    laser: DfbLaser = field(default_factory=paper_dfb)
    refractive_index: float = 1.0
    echo_codes: float = 1500.0      # beat amplitude at <= 0.1 m and 320 mA, ~1/R beyond
    echo_ref_m: float = 0.1
    noise_codes: float = 25.0       # rms white noise of the beat channel
    leak_codes: float = 800.0       # intensity triangle leaking through the balanced detector
    lens_distance_m: float = 0.012  # internal reflection of the collimating lens
    lens_codes: float = 60.0
    sync_codes: float = 6000.0      # sync amplitude for the full current swing
    sync_noise_codes: float = 4.0
    sync_delay_samples: float | None = None
    start_phase: float | None = None
    table_points: int = 25
    table_noise_hz: float = 5e6     # rms error of the offline wavelength meter (0.04 pm)
    thermal_lag_s: float = 0.0      # first-order lag of the thermal part of the tuning
    thermal_fraction: float = 0.8   # share of the tuning that is thermal (the rest: carriers)
    snr_db: float | None = None     # target's per-sample SNR at 0.3 m, mid-sweep; sets the noise
    reflectors: tuple[tuple[float, float], ...] = ()   # static echoes: (distance m, amplitude codes)
    movers: tuple = ()              # other moving echoes: Mover, or (trajectory, amplitude codes)
    target_hidden: tuple[tuple[float, float], ...] = ()   # (start, end s) where the target is hidden
    speckle_s: float = 0.0          # correlation time of the target's speckle fading (0: none)
    rin_db_hz: float | None = None  # laser relative intensity noise, one-sided (dB/Hz)
    headroom: float | None = HEADROOM  # the gain keeps the noise's rms this far below full scale;
                                       # None: no gain setting, noise peaks reach full scale

    def echo_amplitude(self, distance_m):
        """Beat amplitude (codes, at 320 mA) of the target at `distance_m`: falls as 1/R
        beyond `echo_ref_m` (a diffuse target filling less of the beam)."""
        return self.echo_codes * np.minimum(1.0, self.echo_ref_m / np.maximum(distance_m, 1e-6))

    @property
    def beat_noise_codes(self) -> float:
        """rms white noise of the beat channel: `noise_codes`, or the level that gives
        the target `snr_db` per sample (amplitude A: SNR = A^2 / 2 sigma^2) at 0.3 m."""
        if self.snr_db is None:
            return self.noise_codes
        return float(self.echo_amplitude(SNR_REF_M) / np.sqrt(2 * 10 ** (self.snr_db / 10)))


def _triangle(phase):
    """Unit triangle: 0 at phase 0, 1 at 0.5; returns value and d(value)/d(phase)."""
    p = phase - np.floor(phase)
    rising = p < 0.5
    return np.where(rising, 2 * p, 2 - 2 * p), np.where(rising, 2.0, -2.0)


def thermal_offset(phase, lag_s: float, period_s: float, span_a: float):
    """Lag of a first-order-filtered triangle behind the current, in steady state.

    The thermal current I_th follows dI_th/dt = (I - I_th) / lag. For a triangle of
    slope +-r (A/s) and half-period T, x = I_th - I obeys x' = -x/lag -+ r, whose
    periodic solution starts each rising half at x_a = r lag tanh(T / 2 lag) and each
    falling half at -x_a. Returns x (A) and dx/dt (A/s) at `phase` (periods).
    """
    p = phase - np.floor(phase)
    if lag_s <= 0:
        zero = np.zeros_like(p)
        return zero, zero
    half = period_s / 2
    r = span_a / half
    rising = p < 0.5
    s = np.where(rising, p, p - 0.5) * period_s
    x_rise = -r * lag_s + r * lag_s * (np.tanh(half / (2 * lag_s)) + 1) * np.exp(-s / lag_s)
    x = np.where(rising, x_rise, -x_rise)
    slope = np.where(rising, r, -r)
    return x, -x / lag_s - slope


def phase_noise(walk: np.ndarray, tau_s, fs: float, sigma: float, rng: np.random.Generator):
    """phi(t) - phi(t - tau) of the laser's random-walk phase `walk` (HISTORY samples of
    history, then one per sample), with a Brownian bridge inside a sample."""
    m = walk.size - HISTORY
    lag = np.asarray(tau_s, np.float64) * fs
    k = np.floor(lag).astype(np.int64)
    frac = lag - k
    if k.ndim:                                  # one lag a sample: gathered
        back = HISTORY + np.arange(m) - k
        then, before = walk[back], walk[back - 1]
    else:                                       # a fixed reflector: one slice
        then, before = walk[HISTORY - k: walk.size - k], walk[HISTORY - k - 1: walk.size - k - 1]
    bridge = frac * (then - before) + np.sqrt(frac * (1 - frac)) * sigma * rng.standard_normal(m)
    return walk[HISTORY:] - then + bridge


def speckle_field(duration_s: float, corr_s: float, rng: np.random.Generator):
    """A complex Gaussian field g(t), E|g|^2 = 1, with autocorrelation exp(-(dt/corr)^2):
    circular white noise smoothed by a Gaussian of std corr/2, tabulated on a grid.
    |g| is Rayleigh-distributed (fully developed speckle). Returns g(t) as a callable."""
    step = corr_s / SPECKLE_GRID
    n = int(np.ceil(duration_s / step)) + 2
    pad = 4 * SPECKLE_GRID
    white = rng.standard_normal((2, n + 2 * pad)) / np.sqrt(2)
    sigma = SPECKLE_GRID / 2
    # filtered unit-variance white noise has variance 1 / (2 sqrt(pi) sigma)
    g = gaussian_filter1d(white, sigma, axis=1)[:, pad:-pad] * np.sqrt(2 * np.sqrt(np.pi) * sigma)
    grid = step * np.arange(n)
    return lambda t: np.interp(t, grid, g[0]) + 1j * np.interp(t, grid, g[1])


def simulate_capture(path, trajectory: Trajectory, duration_s: float, seed: int = 0,
                     config: SimulationConfig | None = None, start_s: float = 0.0,
                     compression: str | None = None,
                     progress: Callable[[int, int], None] | None = None) -> dict:
    """Write a simulated capture of `trajectory` to `path` and return its hidden parameters.

    Parameters
    ----------
    path : path-like
        Output capture file (written atomically).
    trajectory : Trajectory
        Target motion; its time `start_s` is sample 0 of the capture.
    duration_s : float
        Capture length in seconds.
    seed : int
        Seed of every random draw: the same seed gives the same file.
    config : SimulationConfig
        Instrument parameters.
    progress : callable(done_samples, total_samples), optional

    Returns
    -------
    dict with the drawn sync delay (samples) and start phase.
    """
    cfg = config or SimulationConfig()
    rng = np.random.default_rng(seed)
    fs, mod, laser, n_idx = cfg.sample_rate_hz, cfg.modulation, cfg.laser, cfg.refractive_index
    delay = rng.uniform(-40, 40) if cfg.sync_delay_samples is None else cfg.sync_delay_samples
    phase0 = rng.uniform(0, 1) if cfg.start_phase is None else cfg.start_phase
    target_phase = rng.uniform(0, 2 * np.pi)
    table_i, table_f = laser.tuning_table(rng, cfg.table_points, noise_hz=cfg.table_noise_hz)
    samples = int(round(duration_s * fs))
    lo, hi = -(2 ** (cfg.bits - 1)), 2 ** (cfg.bits - 1) - 1
    span = mod.current_max_a - mod.current_min_a
    sigma_pn = np.sqrt(2 * np.pi * laser.linewidth_hz / fs)  # rad per sample, random walk
    hist = np.zeros(HISTORY)  # laser phase of the last HISTORY samples
    tau_lens = 2 * cfg.lens_distance_m * n_idx / C
    noise = cfg.beat_noise_codes
    # below about -11 dB at 0.3 m the noise would clip the ADC: the whole beat is scaled
    # down as a lab's gain setting would (1.0 otherwise, or with no headroom kept)
    gain = 1.0 if cfg.headroom is None else min(1.0, 2 ** (cfg.bits - 1) / (cfg.headroom * max(noise, 1e-9)))
    speckle = speckle_field(duration_s, cfg.speckle_s, rng) if cfg.speckle_s > 0 else None
    walls = [(2 * d * n_idx / C, a, rng.uniform(0, 2 * np.pi)) for d, a in cfg.reflectors]
    movers = [(m if isinstance(m, Mover) else Mover(*m), rng.uniform(0, 2 * np.pi)) for m in cfg.movers]
    rin = 0.0 if cfg.rin_db_hz is None else np.sqrt(10 ** (cfg.rin_db_hz / 10) * fs / 2)

    writer = CaptureWriter(path, samples, fs, cfg.bits, mod, table_i, table_f,
                           refractive_index=n_idx, compression=compression,
                           attrs={"generator": "fmcw-cl simulate"})
    with writer:
        for start in range(0, samples, CHUNK):
            m = min(CHUNK, samples - start)
            t = (start + np.arange(m)) / fs
            tri, dtri = _triangle(t * mod.frequency_hz + phase0)
            cur = mod.current_min_a + span * tri
            didt = span * mod.frequency_hz * dtri
            # the tuning sees the current with its thermal part lagging; the power does not
            x, dxdt = thermal_offset(t * mod.frequency_hz + phase0, cfg.thermal_lag_s, mod.period_s, span)
            tuned = cur + cfg.thermal_fraction * x
            nu = laser.frequency(tuned)
            dnu = laser.tuning_slope(tuned) * (didt + cfg.thermal_fraction * dxdt)
            power = laser.relative_power(cur)
            if rin:
                power = power * (1 + rng.normal(0, rin, m))

            dist = trajectory.distance_at(t + start_s)
            tau = 2 * dist * n_idx / C
            walk = np.concatenate([hist, hist[-1] + np.cumsum(rng.normal(0, sigma_pn, m))])
            hist = walk[-HISTORY:]

            def echo(tau_s, offset, nu=nu, dnu=dnu, walk=walk):
                # beat phase of a reflector at delay tau_s, laser phase noise included
                cycles = nu * tau_s - dnu * tau_s * tau_s / 2
                return 2 * np.pi * (cycles % 1.0) + phase_noise(walk, tau_s, fs, sigma_pn, rng) + offset

            phase = echo(tau, target_phase)
            amp = cfg.echo_amplitude(dist) * power
            if cfg.target_hidden:
                amp = amp * visibility(t + start_s, cfg.target_hidden)
            if speckle is not None:
                g = speckle(t)
                amp = amp * np.abs(g)
                phase = phase + np.angle(g)
            lens = nu * tau_lens - dnu * tau_lens**2 / 2
            beat = (amp * np.cos(phase)
                    + cfg.lens_codes * power * np.cos(2 * np.pi * (lens % 1.0))
                    + cfg.leak_codes * (power - 1.0)
                    + rng.normal(0, noise, m))
            for tau_w, a_w, ph_w in walls:
                beat += a_w * power * np.cos(echo(tau_w, ph_w))
            for mv, ph_m in movers:
                seen = visibility(t + start_s, mv.hidden) if mv.hidden else 1.0
                tau_m = 2 * mv.trajectory.distance_at(t + start_s) * n_idx / C
                beat += mv.amplitude_codes * seen * power * np.cos(echo(tau_m, ph_m))

            tri_s, _ = _triangle((t - delay / fs) * mod.frequency_hz + phase0)
            sync = cfg.sync_codes * (tri_s - 0.5) + rng.normal(0, cfg.sync_noise_codes, m)
            writer.write(start, np.clip(np.rint(gain * beat), lo, hi).astype(np.int16),
                         np.clip(np.rint(sync), lo, hi).astype(np.int16))
            if progress:
                progress(start + m, samples)

        tt = np.arange(0, samples / fs, TRUTH_STEP_S)
        def seen(hidden):
            return visibility(tt + start_s, hidden) >= 0.5 if hidden else None

        others = [Truth(tt, *mv.trajectory.at(tt + start_s), seen(mv.hidden)) for mv, _ in movers]
        others += [Truth(tt, np.full(tt.size, d), np.zeros(tt.size), np.zeros(tt.size), None, "fixed")
                   for d, _ in cfg.reflectors]
        writer.write_truth(Truth(tt, *trajectory.at(tt + start_s), seen(cfg.target_hidden)), tuple(others))
        writer._file.attrs["sim_seed"] = int(seed)
    return {"sync_delay_samples": float(delay), "start_phase": float(phase0)}


# a lab's instrument, far less kind than the defaults: an intensity triangle of +-150
# codes under 600 codes rms of noise (about -1 dB per sample at 0.3 m), a G(I) table of
# 25 points with 20 MHz rms scatter (an OSA's resolution)
LAB = SimulationConfig(leak_codes=150.0, noise_codes=600.0, table_noise_hz=20e6)
