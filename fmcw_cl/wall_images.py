"""Where a fixed echo shows in a half-sweep de-chirped for a moving target.

The tracker de-chirps each half-sweep at its pair's velocity v (stages.pairing). A still
echo at W is then multiplied by the same exp(-2 pi i v beta_j): its tone at +W, and at
-W its mirror (the beat is real), move by about -v k and smear over the chirp's
nonlinear part. This *image* of a wall left out of the target's band can lie inside
the band: at 5 m/s (the simulator's lab table) 137 mm from the wall, 32 mm wide at half
power, its peak 14 dB under the wall's own (at 1 m/s: 28 mm, 6 mm, 7 dB). Where the
target's peak in one direction fades (or folds into the lowest bins), the tracker may
follow the image: in a landing beside a wall of 1500 codes at 0.087 m, the falling
half-sweeps of 41 pairs followed its image for 2.2 ms, the pairs 45 mm off with
velocities 1.7 m/s off and consistent with them.

A half-sweep's peak cannot be told from an image whose core (its half-power part) it
lies in, where the image comes within IMAGE_MARGIN_DB of the echo's own level, its
pair's weaker half-sweep: an image adds to the half-sweep it lies in and pulls its peak.
Beside a rail at 0.7 m/s, a wall of 150 codes 17-22 mm nearer read 28-33 dB in its rising
half-sweeps, which held the rail's image (read 25-26.5 dB there), and 10-18 dB in its
falling ones: measured against the rising peaks, the image passed as 3.5-5 dB under, and
34 pairs stood 0.6-2.0 mm off, at 0.06 m/s (benchmarks/hunt.py seed 30, capture 24). The
image's level there is the wall's level (fixed_echoes.fixed_echoes) less the power the
de-chirped window loses at that offset, relative to an unsmeared tone's peak
(`image_gain_db`). Levels are read as peaks are, over the floor: the tone's power plus the
noise's, and the window's loss scales the tone's part alone (`image_level_db`). Summed in
dB, a wall read at 7 dB under noise at full scale put its image 11.7 dB under at -4.7 dB,
where the K = 32 integrated peak that was the image read 2.7 dB; what the image reads
there is 1.0 dB.
"""

from __future__ import annotations

import numpy as np

from .stages.doppler import DopplerModel

IMAGE_MARGIN_DB = 3.0   # an echo this far above an image at its peak's place may still be the image: the
                        # levels are measured apart (CFAR tables, peak over the band's mean); on
                        # pairs that followed an image, its estimate lay 1.7 dB under to 6.2 over
IMAGE_CORE_DB = 3.0     # ... where it lies in the image's core: in its tails the image is a slope, no
                        # peak (the pairs that followed an image lay 1.7 dB under its top at most)
IMAGE_REACH_M = 0.01    # images are computed for peaks within this of the image's centre ...
IMAGE_REACH_SHARE = 0.6  # ... plus this share of its shift |v k|: it holds 20 dB of its
                         # power within 0.4 of the shift of its centre
VELOCITY_STEP = 5e-3     # m/s: an image moves 0.14 mm (0.3 bins) a step
BLOCK = 256              # velocities whose spectra are taken at once
GAIN_BOUND_DB = 0.01     # no image keeps more than an unsmeared tone's power (|sum w e^(i phi)| <= sum w)


def image_gain_db(beta: np.ndarray, velocity: np.ndarray, offset_m: np.ndarray, window: np.ndarray,
                  model: DopplerModel) -> tuple[np.ndarray, np.ndarray]:
    """Power (dB, relative to the peak of an unsmeared tone) of a still tone's image in
    half-sweeps de-chirped at `velocity` (m/s, one per pair) by the Doppler basis `beta`:
    at `offset_m` (m; one per pair, or rows of them, each row another tone) from the tone
    (nearest bin of the padded FFT), and at the image's own peak (one per pair). The
    velocities are rounded to VELOCITY_STEP (the image moves by 0.07 mm at most): one
    spectrum per step of the velocities asked, however many pairs and tones."""
    own = np.sum(window) ** 2
    offset_m = np.asarray(offset_m)
    k = np.mod(np.round(np.atleast_2d(offset_m) / model.metres_per_bin).astype(np.int64), model.nfft)
    speeds, which = np.unique(np.round(np.asarray(velocity) / VELOCITY_STEP), return_inverse=True)
    at, top = np.empty(k.shape), np.empty(k.shape[1])
    for a in range(0, speeds.size, BLOCK):          # (velocities, nfft) spectra, a block at a time
        v = VELOCITY_STEP * speeds[a:a + BLOCK, None]
        power = np.abs(np.fft.fft(_dechirped(window, v, beta), model.nfft, axis=1)) ** 2
        mine = np.flatnonzero((which >= a) & (which < a + BLOCK))
        rows = which[mine] - a
        at[:, mine] = power[rows[None, :], k[:, mine]]
        top[mine] = power.max(axis=1)[rows]
    with np.errstate(divide="ignore"):
        return 10 * np.log10(at / own).reshape(offset_m.shape), 10 * np.log10(top / own)


def _dechirped(window: np.ndarray, v: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """window * exp(-2 pi i v beta) (rows: velocities `v`, m/s): the cosine and sine of
    the real phase, the values exp gives for a zero real part, in 3/4 of its time."""
    phase = (-2 * np.pi * v) * beta
    out = np.empty(phase.shape, np.complex128)
    np.cos(phase, out=out.real)
    np.sin(phase, out=out.imag)
    out *= window
    return out


def _may_reach(level_db, own_db: np.ndarray) -> np.ndarray:
    """Whether an image of a tone read at `level_db` could come within IMAGE_MARGIN_DB
    of `own_db` at all: at the window's whole power (a smeared image keeps less; the
    slack covers the FFT's rounding), so a pair that cannot takes no spectrum."""
    return _as_strong(level_db, GAIN_BOUND_DB, own_db)


def image_level_db(level_db, gain_db):
    """What an image reads (dB over the floor, as a peak reads: its power plus the
    noise's) where a tone reads `level_db` and the de-chirped window keeps `gain_db` of
    its power (`image_gain_db`): the window scales the tone's power, not the noise's."""
    with np.errstate(invalid="ignore", over="ignore"):
        tone = np.maximum(np.power(10.0, np.asarray(level_db) / 10) - 1, 0.0)
        return 10 * np.log10(1 + tone * np.power(10.0, np.asarray(gain_db) / 10))


def _as_strong(level_db, gain_db, own_db: np.ndarray) -> np.ndarray:
    """Whether an image (a tone read at `level_db`, the window keeping `gain_db` of its
    power) comes within IMAGE_MARGIN_DB of the echo's own level `own_db` (dB)."""
    return image_level_db(level_db, gain_db) >= own_db - IMAGE_MARGIN_DB


def confused(velocity: np.ndarray, peaks_m: tuple, snr_db: tuple, walls_m: np.ndarray, walls_db: np.ndarray,
             model: DopplerModel, window: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Which pairs of `rows` (a boolean mask) have a half-sweep whose de-chirped peak
    (`peaks_m`: rising, falling; m) could be the image of a fixed echo that is not the
    target (`walls_m`, their levels `walls_db`, dB over the floor): the peak lies in the
    image's core (within IMAGE_CORE_DB of the image's own peak) and the image there comes
    within IMAGE_MARGIN_DB of the echo's level, the weaker of the pair's peaks (`snr_db`:
    rising, falling). The half-sweeps were de-chirped at `velocity` (m/s, per pair)."""
    out = np.zeros(rows.size, bool)
    v = np.asarray(velocity, np.float64)
    own = np.fmin(*snr_db)                           # the echo's level: where no image adds to it
    tones = np.concatenate([walls_m, -np.asarray(walls_m)])      # each wall's tone and its mirror
    levels = np.concatenate([walls_db, walls_db])
    reach = _may_reach(levels[:, None], own[None, :])      # (tones, pairs)
    for beta, k, peak in zip((model.beta_rise, model.beta_fall), model.k, peaks_m,
                             strict=True):
        shift = -v * k                               # where an image's centre lies from its tone
        offset = peak[None, :] - tones[:, None]      # (tones, pairs)
        near = rows & reach & (np.abs(offset - shift) <= IMAGE_REACH_M + IMAGE_REACH_SHARE * np.abs(shift))
        idx = np.flatnonzero(near.any(axis=0))
        if idx.size:                                 # one spectrum per velocity for all tones
            at, top = image_gain_db(beta, v[idx], offset[:, idx], window, model)
            core = at >= top - IMAGE_CORE_DB
            strong = _as_strong(levels[:, None], at, own[idx])
            out[idx] |= (near[:, idx] & core & strong).any(axis=0)
    return out


def confused_moving(velocity: np.ndarray, peaks_m: tuple, snr_db: tuple, other_m: np.ndarray,
                    other_mps: np.ndarray, other_db: float, model: DopplerModel, window: np.ndarray,
                    rows: np.ndarray) -> np.ndarray:
    """`confused` for another object that moves: at `other_m` (m) with `other_mps` (m/s)
    at each pair (NaN: not there). Its tone carries its own Doppler term, so a
    half-sweep de-chirped at v shows it as a still tone de-chirped at v - u (its mirror,
    the conjugate, at v + u); `other_db` is its level (dB over the floor): one, or per
    pair in its rising and falling half-sweeps, (2, pairs)."""
    out = np.zeros(rows.size, bool)
    v = np.asarray(velocity, np.float64)
    own = np.fmin(*snr_db)
    levels = np.broadcast_to(np.asarray(other_db, np.float64), (2, rows.size))
    there = (rows & np.isfinite(other_m) & np.isfinite(other_mps) & np.isfinite(v)
             & _may_reach(np.max(levels, axis=0), own))
    for sign in (1.0, -1.0):                       # the tone, then its mirror
        rel = v - sign * np.nan_to_num(other_mps)
        tone = sign * np.nan_to_num(other_m)
        for beta, k, peak, level in zip((model.beta_rise, model.beta_fall), model.k,
                                        peaks_m, levels, strict=True):
            shift = -rel * k
            offset = peak - tone
            near = there & (np.abs(offset - shift) <= IMAGE_REACH_M + IMAGE_REACH_SHARE * np.abs(shift))
            idx = np.flatnonzero(near)
            if idx.size:
                at, top = image_gain_db(beta, rel[idx], offset[None, idx], window, model)
                core = at[0] >= top - IMAGE_CORE_DB
                strong = _as_strong(level[idx], at[0], own[idx])
                out[idx] |= core & strong
    return out
