"""The processor interface: the spectrum steps of the tracker and the verification's
tests (`SpectrumOps`), which both backends implement: numpy's (`NUMPY`, the
processor.ChunkProcessor it is a base of) and a device's
(opencl.processor.OpenCLProcessor), with the same arguments and results. The stage
functions that take an instance (stages.pairing's tracker, stages.verification) are
imported where a method calls them: they import this module for their default.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from .stages import bank, integrate, phase
from .stages.doppler import DopplerModel, measure, power
from .stages.spectrum import Search

if TYPE_CHECKING:
    from .stages.pairing import Passes, Times


class SpectrumOps:
    """The spectrum steps of the tracker and the verification's tests in numpy; a
    backend swaps in its own (opencl.processor.OpenCLProcessor), with the same arguments
    and results."""

    def measure(self, x, beta, v, model: DopplerModel, search: Search, rows=None,
                direction: int = 0) -> tuple:
        return measure(x, beta, v, model, search, rows, direction)

    def measure_each(self, xs, betas, v, model: DopplerModel, search: Search, rows=None) -> list[tuple]:
        """`measure` of each x of `xs` (a pair's rising and falling half-sweeps, in that
        direction's bands) with its beta of `betas`, the same velocities and rows (a
        backend: in one round trip)."""
        return [self.measure(x, beta, v, model, search, rows, j)
                for j, (x, beta) in enumerate(zip(xs, betas, strict=True))]

    def track(self, rows: tuple, times: Times, model: DopplerModel, search: Search, iterations: int,
              single: bool) -> tuple[tuple, Passes | None]:
        """The tracker's plain pass of both directions of `rows` (every echo with
        `search.echoes`) and, when `single`, its de-chirp passes without integration
        (`passes`; a backend: on the device, its state read once)."""
        from .stages.pairing import passes

        first = tuple(self.plain_pass(rows, model, search, times))
        if not single:
            return first, None
        return first, passes(rows, times, model, replace(search, echoes=False), iterations, self, first, 1)

    def integrated(self, rows: tuple, times: Times, model: DopplerModel, search: Search, iterations: int,
                   k: int) -> Passes:
        """The tracker's de-chirp passes on K-window integrated spectra of both
        directions of `rows` (`passes` with k > 1; a backend: on the device, its state
        read once)."""
        from .stages.pairing import passes

        return passes(rows, times, model, search, iterations, self, None, k)

    def plain_pass(self, rows: tuple, model: DopplerModel, search: Search,
                   times: Times | None = None) -> list[tuple]:
        """`measure_each` of both directions of `rows` at 0 m/s: the tracker's first pass
        (`times`: the pairs'; each of its groups measured as if alone: a backend that takes
        two rows a transform pairs them within a group)."""
        return self.measure_each(rows, (model.beta_rise, model.beta_fall), None, model, search)

    def power(self, x, beta, v, nfft: int, rows=None) -> np.ndarray:
        return power(x, beta, v, nfft, rows)

    def residuals(self, t, dist, vel, trusted, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """The continuity residuals (m) of the pairs `rows` (all when None) against the
        `trusted` ones, and how many vouch for each (`_residuals`, one group)."""
        from .stages.verification import _residuals

        return _residuals(t, dist, vel, trusted, rows)

    def disagreed(self, t, dist, vel, ok) -> np.ndarray:
        from .stages.verification import disagreed

        return disagreed(t, dist, vel, ok)

    def power_each(self, jobs: list, nfft: int) -> list[np.ndarray]:
        """`power` of each (x, beta, v) of `jobs`, rows of any count each (a backend: one
        download)."""
        return [self.power(x, beta, v, nfft) for x, beta, v in jobs]

    def spectra(self, x, beta, v, nfft: int, rows=None, store=None):
        """`store` (a (sweeps, nfft/2) array, new when None) with the rows `rows` (all
        when None) replaced by their power spectra, de-chirped at v (plain when None)."""
        spec = power(x, beta, v, nfft, rows)
        if store is None:
            return spec
        store[slice(None) if rows is None else rows] = spec
        return store

    def integrated_peaks(self, store, disp: np.ndarray, k: int, search: Search,
                         bounds: np.ndarray | None = None, direction: int = 0) -> tuple:
        """(bin, SNR dB, count) of the K-window integrated spectra (stages.integrate;
        `bounds`: each row's group's first and last row, None: one group) in
        `direction`'s bands (0: rising, 1: falling)."""
        return integrate.peaks(store, disp, k, search, bounds, direction)

    def survey(self, x, beta, v, nfft: int, rows, lo: int, tracked_bin, plain_bin, others) -> tuple:
        """echoes.hidden of the rows `rows` of x: (ratio, centroid, found) from their plain
        spectra and those de-chirped at v, and the plain spectra's echoes.block_sums."""
        from .echoes import block_sums, hidden

        plain = power(x, None, None, nfft, rows)
        return (*hidden(plain, power(x, beta, v, nfft, rows), lo, tracked_bin, plain_bin, others),
                block_sums(plain))

    def bank_each(self, xs, betas, rows, nfft: int, lo: int) -> tuple:
        """stages.bank.detect of the rows `rows` of each x of `xs` (a pair's two
        directions) with its beta of `betas`: the CFAR echoes (from bin `lo`) of each
        row de-chirped at each trial velocity (a backend: one trip)."""
        return tuple(bank.detect(x, beta, rows, nfft, lo) for x, beta in zip(xs, betas, strict=True))

    def phasors_each(self, xs, betas, v, bins, nfft: int) -> list[np.ndarray]:
        """stages.phase.phasors of each x of `xs` (a pair's two directions) with its beta
        and peak bins of `betas` and `bins`, the same velocities (a backend: one trip)."""
        return [phase.phasors(x, beta, v, b, nfft) for x, beta, b in zip(xs, betas, bins, strict=True)]

    def survey_each(self, xs, betas, v, nfft: int, rows, lo: int, tracked_bins, plain_bins, others) -> list:
        """`survey` of each x of `xs` (a pair's two directions) with its beta, tracked and
        plain bins and other echoes, the same rows and velocities (a backend: one trip)."""
        return [self.survey(*a[:2], v, nfft, rows, lo, *a[2:])
                for a in zip(xs, betas, tracked_bins, plain_bins, others, strict=True)]


NUMPY = SpectrumOps()
