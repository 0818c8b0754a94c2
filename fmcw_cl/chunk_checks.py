"""A chunk's pairs after the tracker: which of them the chunk owns (`owned`), the
2N-point range check of the owned ones (`RangeCheck`) and the survey of their hidden
echoes (`Survey`; `no_survey` where nothing was surveyed), with the velocity bank's
points of the first conversion (stages.bank).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import echoes
from .stages import bank, doppler, faults, pairing
from .stages.spectrum import Search

CHECK_STRIDE = 4             # the 2N-point range check runs on every 4th pair near the limit,
CHECK_STRIDE_FAR = 16        # ... every 16th where every distance of the chunk is below
CHECK_NEAR = 0.75            # this share of the unambiguous range
SURVEY_KEYS = ("time_s", "rising", "ratio", "distance_m", "found", *echoes.MEAN_KEYS, *bank.POINT_KEYS)


def owned(first: np.ndarray, start: int, stop: int) -> slice | np.ndarray:
    """The pairs a chunk owns, those whose first turn (`first`, sync samples) lies in
    its core [start, stop): a slice where they are one run, as they are where `first`
    increases, so that taking them makes views, not copies; else their indices."""
    idx = np.flatnonzero((first >= start) & (first < stop))
    if idx.size and idx[-1] - idx[0] + 1 == idx.size:
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


@dataclass(frozen=True)
class RangeCheck:
    """The 2N-point range check of a chunk's owned pairs: the pairs `checked`, the
    resampling jobs of their rising and falling half-sweeps at 2N points, its window,
    model and search."""

    checked: np.ndarray
    jobs: list
    window: np.ndarray
    model: doppler.DopplerModel
    search: Search

    @classmethod
    def of(cls, plan, hs, r: np.ndarray, f: np.ndarray, res: pairing.PairResult) -> RangeCheck:
        """The 2N-point range check of pairs (r, f) of the half-sweeps `hs` with the
        tracker's results `res` under `plan`, on the plain spectra (a target whose
        Doppler-shifted plain peak folds is flagged too: the plain pass that starts the
        tracker cannot measure it), run on every CHECK_STRIDE-th pair (`beyond`). A
        target only crosses the limit through N-point distances near it: in a chunk whose
        plain and Doppler-free distances all stay below CHECK_NEAR of it, every
        CHECK_STRIDE_FAR-th pair is checked (a target beyond the range from the start is
        still found)."""
        lut2, win2, model2 = plan.check
        seen = np.concatenate([res.dist_rise, res.dist_fall, res.dechirped_rise, res.dechirped_fall,
                               res.distance])
        near = np.any(seen > CHECK_NEAR * plan.lut.unambiguous_range_m)
        stride = CHECK_STRIDE if near else CHECK_STRIDE_FAR
        checked = np.arange(0, r.size, stride)
        if checked[-1] != r.size - 1:
            checked = np.append(checked, r.size - 1)
        sides = ((r[checked], lut2.u_rise), (f[checked], lut2.u_fall))
        return cls(checked, [(hs.start[idx], hs.length[idx], u) for idx, u in sides], win2, model2,
                   Search(plan.search.lo, model2.nfft // 2))

    def beyond(self, got: list, res: pairing.PairResult, lut) -> np.ndarray:
        """Which of the pairs of `res` lie beyond the unambiguous range of `lut`, from the
        checked pairs' 2N-point peaks `got`: a pair is flagged when a checked pair on
        either side of it is (a target crosses the range limit within a few pairs, where
        the N-point distance is ambiguous anyway)."""
        checked, n = self.checked, res.distance.size
        beyond = np.zeros(checked.size, bool)
        for (d2, s2), dn in zip(got, (res.dist_rise[checked], res.dist_fall[checked]), strict=True):
            beyond |= faults.beyond_range(d2, s2, lut.unambiguous_range_m, pairing.SNR_MIN_DB, dn)
        right = np.searchsorted(checked, np.arange(n))          # first checked pair >= i
        left = np.searchsorted(checked, np.arange(n), side="right") - 1
        return beyond[right] | beyond[np.maximum(left, 0)]


@dataclass(frozen=True)
class Survey:
    """The survey of a chunk's hidden echoes: the surveyed pairs `idx` and `survey_each`'s
    arguments for them; `bank`: the pairs of them that go through the velocity bank
    (None: none)."""

    idx: np.ndarray
    args: tuple
    bank: np.ndarray | None = None

    @property
    def bank_args(self) -> tuple:
        """`bank_each`'s arguments: both directions' rows and bases, the picked pairs,
        the FFT length and the first bin."""
        xs, betas, _, nfft, _, lo, *_ = self.args
        return xs, betas, self.bank, nfft, lo

    def points(self, got: tuple | None, times: tuple, model: doppler.DopplerModel) -> dict:
        """The bank's points (stages.bank.points) from `bank_each`'s echoes `got` (None:
        no bank), the pairs' rising and falling times (s) `times`."""
        if got is None or self.bank is None:
            return bank.no_points()
        return bank.points(got, times[0][self.bank], times[1][self.bank], model)

    def table(self, got: list, times: tuple, model: doppler.DopplerModel) -> dict:
        """The survey's columns (SURVEY_KEYS) from survey_each's results `got`, the pairs'
        rising and falling times (s) `times`: per surveyed half-sweep, and the peaks of
        each direction's mean spectra (echoes.mean_peaks, at their pairs' mean time)."""
        counts = echoes.block_rows(self.idx.size)
        t_mean = echoes.block_sums(0.5 * (times[0][self.idx, None] + times[1][self.idx, None]))[:, 0] / counts
        means = []
        for rising, g in zip((True, False), got, strict=True):
            block, b, snr = echoes.mean_peaks(g[3], counts, self.args[5])
            means.append((t_mean, np.full(t_mean.size, rising), t_mean[block], np.full(block.size, rising),
                          b * model.metres_per_bin, snr))
        return {"time_s": np.concatenate([t[self.idx] for t in times]),
                "rising": np.repeat([True, False], self.idx.size),
                "ratio": np.concatenate([g[0] for g in got]),
                "distance_m": np.concatenate([g[1] * model.metres_per_bin for g in got]),
                "found": np.concatenate([g[2] for g in got]),
                **dict(zip(echoes.MEAN_KEYS, map(np.concatenate, zip(*means, strict=True)), strict=True)),
                **bank.no_points()}

    def spectrum(self, got: list) -> tuple[np.ndarray, int]:
        """The surveyed half-sweeps' plain power spectra summed per direction (rising,
        falling), from survey_each's results `got`, and how many of a direction."""
        return np.stack([g[3].sum(axis=0, dtype=np.float64) for g in got]), int(self.idx.size)


def no_survey() -> dict:
    """The survey of a chunk that surveyed nothing."""
    return {k: np.zeros(0, bool if k == "found" or k.endswith("rising") else float) for k in SURVEY_KEYS}
