"""The Doppler model of the half-sweeps and the solve of a pair (stage 6, with stages.pairing).

What the LUT and the window imply for the Doppler term of a half-sweep resampled at
uniform optical frequency (`DopplerModel`, `doppler_model`); the power spectra and
peaks of half-sweeps de-chirped at given velocities (`power`, `measure`); and a
pair's Doppler-free distance and velocity from its two apparent distances
(`solve_pair`), with the bias of that distance under acceleration
(`acceleration_bias`). The tracker (stages.pairing) iterates these.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics import C
from . import cfar
from .lut import Lut
from .spectrum import Search, find_peaks, power_spectra


@dataclass(frozen=True)
class DopplerModel:
    """What the LUT and the window imply for the Doppler term.

    Attributes
    ----------
    beta_rise, beta_fall : (N,) Doppler phase in cycles per (m/s) at each resampled point.
    k_rise, k_fall : apparent-distance shift per m/s of uncorrected velocity (s);
        the window-weighted slope of beta, i.e. the effective sweep time.
    metres_per_bin : distance of one bin of the padded FFT (m).
    nfft : padded FFT length.
    q_rise, q_fall : apparent-distance shift per m/s^2 of acceleration about the
        half-sweep's own centre (s^2): the window-weighted slope of the displacement
        a (t - t_c)^2 / 2 as a phase (`acceleration_bias`).
    """

    beta_rise: np.ndarray
    beta_fall: np.ndarray
    k_rise: float
    k_fall: float
    metres_per_bin: float
    nfft: int
    q_rise: float = 0.0
    q_fall: float = 0.0

    @property
    def k(self) -> tuple[float, float]:
        """(k_rise, k_fall): each direction's shift per m/s (s), as the scene's rules
        take them."""
        return self.k_rise, self.k_fall


def doppler_model(lut: Lut, half_sweep_s: float, nfft: int, win: np.ndarray) -> DopplerModel:
    """Build the de-chirp bases and effective times for a LUT and window."""
    n, nidx = lut.points, lut.refractive_index
    dnu = lut.bandwidth_hz / n
    j = np.arange(n) - (n - 1) / 2
    metres_per_cycle = C / (2 * nidx * dnu)   # distance of a tone of 1 cycle per point

    def basis(u):
        return (2 * nidx / C) * lut.nu_hz * (u - 0.5) * half_sweep_s

    def k_eff(beta):
        # a small phase error eps_j moves the peak by the window-weighted LS slope
        return metres_per_cycle * np.sum(win * j * beta) / np.sum(win * j * j)

    def q_eff(u):
        # the phase of the displacement a (t - t_c)^2 / 2, per m/s^2, in cycles
        return k_eff((nidx / C) * lut.nu_hz * np.square((u - 0.5) * half_sweep_s))

    br, bf = basis(lut.u_rise), basis(lut.u_fall)
    for beta in (br, bf):
        beta.flags.writeable = False       # a device keeps its first upload (Buffers.constant)
    return DopplerModel(br, bf, float(k_eff(br)), float(k_eff(bf)),
                        metres_per_cycle / nfft, nfft, float(q_eff(lut.u_rise)), float(q_eff(lut.u_fall)))


def power(x: np.ndarray, beta: np.ndarray | None, v: np.ndarray | None, nfft: int,
          rows: np.ndarray | None = None) -> np.ndarray:
    """Power spectra (sweeps, nfft/2) of half-sweeps de-chirped at velocities v (plain
    when v is None), of the rows `rows` of x only when given."""
    if rows is not None:
        x = x[rows]
    if v is not None:
        x = x * np.exp(-2j * np.pi * np.outer(v, beta))
    return power_spectra(x, nfft)


def measure(x: np.ndarray, beta: np.ndarray, v: np.ndarray | None, model: DopplerModel,
            search: Search, rows: np.ndarray | None = None, direction: int = 0) -> tuple:
    """Apparent distance (m) and SNR (dB) of half-sweeps de-chirped at velocities v
    (plain spectra when v is None), of the rows `rows` of x only when given; with
    `search.echoes`, every echo above the band's start (cfar.Detections; beyond its
    end too: a wall behind --max-range stays visible) as a third item. `direction`
    (0: rising, 1: falling) picks the rows' own bands where the search has them."""
    spec = power(x, beta, v, model.nfft, rows)
    pk = find_peaks(spec, *search.band(direction, rows))
    got = (pk.bin * model.metres_per_bin, pk.snr_db)
    return (*got, cfar.detect(spec, search.lo)) if search.echoes else got


def solve_pair(d_r, d_f, v0, half_gap, model: DopplerModel):
    """Distance at the pair's centre time and velocity from two apparent distances.

    d_r = R_m - v h + dv k_r and d_f = R_m + v h + dv k_f with v = v0 + dv, where
    h is half the time between the sweeps' centres (the target moves meanwhile).
    """
    dv = (d_f - d_r - 2 * v0 * half_gap) / (2 * half_gap + model.k_fall - model.k_rise)
    dist = 0.5 * (d_r + d_f) - 0.5 * dv * (model.k_rise + model.k_fall)
    return dist, v0 + dv, dv


def acceleration_bias(acceleration, half_gap, model: DopplerModel):
    """The bias (m) of `solve_pair`'s distance for a target accelerating at
    `acceleration` (m/s^2). Both half-sweeps are de-chirped at the pair's one velocity
    (its value at the pair's centre), but the target moves by a tau^2 / 2 more, tau the
    time from that centre: tau = t - t_c -+ h in the rising and falling half-sweep (h =
    `half_gap`, s). As a phase its window-weighted slope moves each apparent distance,
    by q -+ h k + h^2 / 2 per m/s^2 (q: the slope of a (t - t_c)^2 / 2, `q_rise`,
    `q_fall`; -+ h k: the velocity a h off the de-chirp's; h^2 / 2: where the target is at
    the half-sweep's centre), and `solve_pair` carries them into the distance. At the
    paper's sweep 0.31 um per m/s^2 (0.11 mm at a jump's 360 m/s^2; 0.29 seen on
    constant accelerations of 30-300 m/s^2): the distance drifts against the integrated
    velocity by the acceleration's change, which the sync delay's refinement took for a
    delay error (7 samples on a 15 ms take-off). The velocity's bias, (c_f - c_r) over
    the solve's denominator, vanishes for a table's symmetric sweeps."""
    h = half_gap
    c_r = model.q_rise - h * model.k_rise + 0.5 * h * h
    c_f = model.q_fall + h * model.k_fall + 0.5 * h * h
    dv = (c_f - c_r) / (2 * h + model.k_fall - model.k_rise)
    return acceleration * (0.5 * (c_r + c_f) - 0.5 * dv * (model.k_rise + model.k_fall))
