"""Stage 6b: the beat's phase at each half-sweep's peak (the displacement's raw reading).

Resampled at uniform optical frequency nu_j (increasing in both directions,
stages.lut), a target at R has the beat phase psi_j = 2 pi nu_j tau(t_j), tau = 2 n R / c.
The half-sweep de-chirped at its pair's velocity v (stages.pairing: the motion referred
to the half-sweep's centre time t_c) and summed at its peak's frequency f (cycles per
nfft points) about the centre point j_c = (N - 1) / 2,

    z = sum_j x_j exp(-2 pi i [v beta_j + f (j - j_c) / nfft]),

is (A / 2) sum_j w_j exp(i psi_c) for a tone, whose angle reads 4 pi n nu_c R(t_c) / c:
the distance at the half-sweep's centre time, at the centre point's optical frequency
nu_c (the LUT's mean). Referred to the centre, the angle does not move with a small
error of f or v (their phase slopes cross zero there); the symmetric Hann window keeps
the sum real about it. A real beat's negative-frequency image lies 2f away, under the
window's sidelobes.
"""

from __future__ import annotations

import numpy as np

from ..physics import C

BLOCK = 512          # rows summed at once (bounds the temporary complex arrays)


def phasors(x: np.ndarray, beta: np.ndarray, v: np.ndarray | None, bins: np.ndarray, nfft: int) -> np.ndarray:
    """Complex value of each row's de-chirped spectrum at its fractional bin, referred
    to the row's centre point.

    Parameters
    ----------
    x : (P, N) float
        Resampled, windowed half-sweeps of one direction.
    beta : (N,) float
        Doppler phase of that direction (cycles per m/s, doppler.DopplerModel).
    v : (P,) float or None
        Each row's de-chirp velocity (m/s); None: plain (no de-chirp).
    bins : (P,) float
        Each row's peak (fractional bin of the nfft-point transform).
    nfft : int
        The transform's length.

    Returns
    -------
    (P,) complex128
    """
    rows, points = np.shape(x)
    j = (np.arange(points) - 0.5 * (points - 1)) / nfft
    out = np.empty(rows, np.complex128)
    for a in range(0, rows, BLOCK):
        b = min(rows, a + BLOCK)
        cycles = np.outer(bins[a:b], j)
        if v is not None:
            cycles += np.outer(v[a:b], beta)
        cycles -= np.rint(cycles)
        # the sine of a fraction of a turn in float32 (2e-7 rad), summed in float64:
        # eight times numpy's complex exponential's speed
        turn = (2.0 * np.pi * cycles).astype(np.float32)
        rows_ab = np.asarray(x[a:b], np.float32)
        out[a:b] = (np.einsum("ij,ij->i", rows_ab, np.cos(turn), dtype=np.float64)
                    - 1j * np.einsum("ij,ij->i", rows_ab, np.sin(turn), dtype=np.float64))
    return out


def radians_per_metre(nu_hz: np.ndarray, refractive_index: float = 1.0) -> float:
    """The phase's rate with distance at the centre point's optical frequency,
    4 pi n nu_c / c (rad/m): 2 pi per half wavelength."""
    return 4.0 * np.pi * refractive_index * float(np.mean(nu_hz)) / C


def centre_moments(u: np.ndarray, half_sweep_s: float, win: np.ndarray) -> tuple[float, float]:
    """The window-weighted mean (s) and half mean square (s^2) of t_j - t_c over the
    LUT's points `u` (fractions of the half-sweep) of one direction: what a velocity
    error dv (dv times the mean) and an acceleration a (a times the half mean square)
    add to that direction's phase distance, the de-chirp being linear in time."""
    dt = (np.asarray(u) - 0.5) * half_sweep_s
    return float(np.sum(win * dt) / np.sum(win)), float(np.sum(win * dt * dt) / (2.0 * np.sum(win)))
