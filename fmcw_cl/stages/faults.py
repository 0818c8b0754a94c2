"""Why a pair is invalid: reason codes and the checks that set them.

Written per pair in ``/track/reason`` and per half-sweep in ``/sweeps/reason`` (a
half-sweep carries its pair's code). When several apply, the first in this order wins:
a missing sync beats a clipped beat beats a weak echo beats an alias beats an
unsettled tracker beats a discontinuous distance (with no echo, the range check only
sees noise); an ambiguous target and an unverified pair come last.

Validity is positive: a pair is valid only when every check passed *and* at least
verification.SUPPORT valid neighbours vouch for its distance (`verified`).
"""

from __future__ import annotations

import numpy as np

from ..spectrum_ops import NUMPY, SpectrumOps
from .verification import verify

OK = 0
SYNC_GAP = 1       # no pair measured here: dropped samples or a broken sync stretch
CLIPPED = 2        # CLIP_SHARE of the beat's codes in the pair's half-sweeps are at full scale
NO_ECHO = 3        # a half-sweep's peak is below the SNR threshold (no target, beam blocked)
BEYOND_RANGE = 4   # the target lies beyond the unambiguous range (its peak is an alias)
UNSTABLE = 5       # the de-chirp did not settle or the velocity disagrees with its neighbours
DISCONTINUOUS = 6  # the distance disagrees with its neighbours' (a fade's noise peak, another echo)
UNVERIFIED = 7     # too few valid neighbours to check the distance against (an isolated pair)
AMBIGUOUS = 8      # the target cannot be told from a fixed echo here (see stages.target)
UNCALIBRATED = 9   # the laser's chirp has left its G(I) table or calibration (peaks far too wide)

REASONS = {
    OK: "ok",
    SYNC_GAP: "sync_gap",
    CLIPPED: "clipped",
    NO_ECHO: "no_echo",
    BEYOND_RANGE: "beyond_range",
    UNSTABLE: "unstable",
    DISCONTINUOUS: "discontinuous",
    UNVERIFIED: "unverified",
    AMBIGUOUS: "ambiguous",
    UNCALIBRATED: "uncalibrated",
}

# each reason in plain words, for a line that says why a capture has no valid pair
MEANINGS = {
    SYNC_GAP: "no sync turning points there (dropped samples, a broken sync)",
    CLIPPED: "the beat is clipped at full scale (lower the detector's gain)",
    NO_ECHO: "no echo stands out of the noise (no target in the beam, too weak, or outside the band)",
    BEYOND_RANGE: "the target lies beyond the unambiguous range (raise --points)",
    UNSTABLE: "the Doppler de-chirp did not settle (motion faster than the tracker follows)",
    DISCONTINUOUS: "the distances jump from pair to pair (a fade's noise peaks, or another echo)",
    UNVERIFIED: "too few valid neighbours vouch for the pairs",
    AMBIGUOUS: "the target cannot be told from another echo",
    UNCALIBRATED: "the laser's chirp has left its G(I) table (fmcw-cl calibrate)",
}

RANGE_MARGIN = 1.02   # a 2N-point peak beyond this share of the N-point range is an alias
ALIAS_M = 0.01        # ... when the N-point peak lies this close to its mirror image


CLIP_BLOCK = 256      # codes per block of the clipping counts
CLIP_SHARE = 0.02     # a pair whose span has this share of clipped codes is flagged


def is_clipped(codes: np.ndarray, full_scale: int) -> np.ndarray:
    """Codes at -full_scale or at full_scale - 1 and beyond."""
    return (codes <= -full_scale) | (codes >= full_scale - 1)


def clip_counts(codes: np.ndarray, block: int, full_scale: int) -> np.ndarray:
    """How many codes of each block of `block` codes (the last one partial) are clipped
    (`is_clipped`), uint16. The numpy twin of the `clip_blocks` kernel (kernels/faults.cl)."""
    hit = is_clipped(codes, full_scale)
    pad = -hit.size % block
    return np.concatenate([hit, np.zeros(pad, bool)]).reshape(-1, block).sum(axis=1).astype(np.uint16)


def clipped_share(starts: np.ndarray, lengths: np.ndarray, counts: np.ndarray, size: int,
                  block: int = CLIP_BLOCK) -> np.ndarray:
    """The share of clipped codes in each span [start, start + length] of a chunk of
    `size` codes, from the blocks' `counts` (`clip_counts`, a backend's): whole blocks
    exactly, the partial blocks at a span's ends pro rata (at most two blocks' worth of
    error in a span of thousands of codes).

    Clipping is judged by its effect: a saturated echo is cut at every crest (a share of
    several per cent even when barely saturated, 2.8 % at 0.1 % over full scale) and
    distorts the spectrum; noise peaks that reach full scale now and then (0.7 % of the
    codes at 2.7 sigma) do not measurably. A pair is CLIPPED from CLIP_SHARE up.
    """
    if size == 0 or not counts.any():            # most chunks: nothing clipped
        return np.zeros(np.size(starts))
    a = np.clip(np.floor(starts), 0, size)
    b = np.clip(np.ceil(starts + lengths) + 1, 0, size)                  # codes [a, b)
    cum = np.r_[0.0, np.cumsum(counts, dtype=np.float64)]
    per = counts.astype(np.float64) / np.minimum(block, size - block * np.arange(counts.size))

    def upto(x):                       # clipped codes in [0, x)
        k = np.minimum((x // block).astype(np.int64), counts.size - 1)
        return cum[k] + per[k] * (x - k * block)

    return (upto(b) - upto(a)) / np.maximum(b - a, 1)


def beyond_range(distance_2n_m: np.ndarray, snr_2n_db: np.ndarray, unambiguous_m: float,
                 snr_min_db: float, distance_n_m: np.ndarray) -> np.ndarray:
    """Half-sweeps whose peak, resampled at twice the points (twice the range), lies
    beyond the unambiguous range U of the N-point resampling, where the N-point peak
    (plain, `distance_n_m`) is its alias: a real beat folds a tone at d in (U, 2U) to
    2U - d. Without that match the 2N-point peak is noise (a half-sweep whose beat
    folds through 0 Hz has no peak in the band, and the largest of twice the noise
    bins then passes the SNR threshold now and then)."""
    alias = np.abs(distance_n_m - (2 * unambiguous_m - distance_2n_m)) < ALIAS_M
    return (snr_2n_db >= snr_min_db) & (distance_2n_m > RANGE_MARGIN * unambiguous_m) & alias


def reasons(valid: np.ndarray, heard: np.ndarray, clip: np.ndarray, alias: np.ndarray,
            continuous: np.ndarray) -> np.ndarray:
    """Per-pair code (uint8) from the tracker's verdict and the fault checks."""
    code = np.full(valid.shape, OK, np.uint8)
    for mask, value in ((~continuous, DISCONTINUOUS), (~valid, UNSTABLE), (alias, BEYOND_RANGE),
                        (~heard, NO_ECHO), (clip, CLIPPED)):
        code[mask] = value          # later assignments take precedence
    return code


def verified(t: np.ndarray, distance: np.ndarray, velocity: np.ndarray, code: np.ndarray,
             ops: SpectrumOps = NUMPY, looks: np.ndarray | None = None) -> np.ndarray:
    """The codes `code` of pairs at times t with the pairs that are OK but not vouched
    for by enough OK neighbours (verification.verify, its tests by `ops`: a processor's;
    `looks`: the half-sweeps each pair's spectra summed) set to UNVERIFIED, or
    DISCONTINUOUS where their neighbours disagree with them."""
    ok, unsupported = verify(t, distance, velocity, code == OK, ops, looks)
    out = code.copy()
    dropped = (code == OK) & ~ok
    out[dropped] = np.where(unsupported[dropped], UNVERIFIED, DISCONTINUOUS)
    return out
