"""Why a pair is invalid: reason codes and the checks that set them.

Written per pair in ``/track/reason`` and per half-sweep in ``/sweeps/reason`` (a
half-sweep carries its pair's code). When several apply, the first in this order wins:
a missing sync beats a clipped beat beats a weak echo beats an alias beats an
unsettled tracker beats a discontinuous distance (with no echo, the range check only
sees noise); an ambiguous target and an unverified pair come last.

Validity is positive: a pair is valid only when every check passed *and* at least
pairing.SUPPORT valid neighbours vouch for its distance (`verified`).
"""

from __future__ import annotations

import numpy as np

from .pairing import verify

OK = 0
SYNC_GAP = 1       # no pair measured here: dropped samples or a broken sync stretch
CLIPPED = 2        # the beat reaches the ADC's full scale inside the pair's half-sweeps
NO_ECHO = 3        # a half-sweep's peak is below the SNR threshold (no target, beam blocked)
BEYOND_RANGE = 4   # the target lies beyond the unambiguous range (its peak is an alias)
UNSTABLE = 5       # the de-chirp did not settle or the velocity disagrees with its neighbours
DISCONTINUOUS = 6  # the distance disagrees with its neighbours' (a fade's noise peak, another echo)
UNVERIFIED = 7     # too few valid neighbours to check the distance against (an isolated pair)
AMBIGUOUS = 8      # the target cannot be told from a fixed echo here (see stages.target)

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
}

RANGE_MARGIN = 1.02   # a 2N-point peak beyond this share of the N-point range is an alias
ALIAS_M = 0.01        # ... when the N-point peak lies this close to its mirror image


CLIP_BLOCK = 256      # codes per block of the clipping flags


def is_clipped(codes: np.ndarray, full_scale: int) -> np.ndarray:
    """Codes at -full_scale or at full_scale - 1 and beyond."""
    return (codes <= -full_scale) | (codes >= full_scale - 1)


def clip_flags(codes: np.ndarray, block: int, full_scale: int) -> np.ndarray:
    """Whether each block of `block` codes (the last one partial) holds a clipped code
    (`is_clipped`). The numpy twin of the `clip_blocks` kernel (kernels/faults.cl)."""
    hit = is_clipped(codes, full_scale)
    pad = -hit.size % block
    return np.concatenate([hit, np.zeros(pad, bool)]).reshape(-1, block).any(axis=1)


def clipped(codes: np.ndarray, starts: np.ndarray, lengths: np.ndarray, full_scale: int,
            flags: np.ndarray | None = None, block: int = CLIP_BLOCK) -> np.ndarray:
    """Whether any sample of each half-sweep [start, start + length] reaches full scale.

    Parameters
    ----------
    codes : (n,) int16 beat codes of the chunk.
    starts, lengths : (S,) half-sweeps in samples of `codes`.
    full_scale : 2^(bits-1); codes at -full_scale or full_scale - 1 are clipped.
    flags : `clip_flags(codes, block, full_scale)` (a backend's), made here when None:
        the codes themselves are read only in the flagged blocks at a span's ends.
    """
    if codes.size == 0:
        return np.zeros(np.size(starts), bool)
    if flags is None:
        flags = clip_flags(codes, block, full_scale)
    a = np.clip(np.floor(starts).astype(np.int64), 0, codes.size)
    b = np.clip(np.ceil(starts + lengths).astype(np.int64) + 1, 0, codes.size)     # samples [a, b)
    count = np.r_[0, np.cumsum(flags)]
    first, last = -(-a // block), b // block                 # whole blocks [first, last)
    out = count[np.maximum(last, first)] > count[first]
    # the partial blocks at a span's ends: read where they are flagged
    ends = flags[np.minimum(a // block, flags.size - 1)] | flags[np.minimum(last, flags.size - 1)]
    for i in np.flatnonzero(~out & (b > a) & ends):
        for lo, hi in ((a[i], min(b[i], first[i] * block)), (max(a[i], last[i] * block), b[i])):
            if hi > lo:
                out[i] |= bool(np.any(is_clipped(codes[lo:hi], full_scale)))
    return out


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


def verified(t: np.ndarray, distance: np.ndarray, velocity: np.ndarray, code: np.ndarray) -> np.ndarray:
    """The codes `code` of pairs at times t with the pairs that are OK but not vouched
    for by enough OK neighbours (pairing.verify) set to UNVERIFIED, or DISCONTINUOUS
    where their neighbours disagree with them."""
    ok, unsupported = verify(t, distance, velocity, code == OK)
    out = code.copy()
    dropped = (code == OK) & ~ok
    out[dropped] = np.where(unsupported[dropped], UNVERIFIED, DISCONTINUOUS)
    return out
