"""Launcher of kernels/track.cl: the tracker's plain pass and de-chirp passes with the
regularisation between them on the device, and the pairs' verdict after them (twin:
fmcw_cl.spectrum_ops.SpectrumOps.track, its `passes` without integration, and
pairing.verdict)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..stages import doppler, groups, integrate, pairing, verification
from ..stages.spectrum import Search
from . import integrate as k_integrate
from . import phase as k_phase
from . import spectrum as k_spectrum
from .buffers import Buffers, DeviceRows, Packed
from .context import Runtime, cl

REACH_MAX = 16      # the running median's half-width the kernel holds (kernels/track.cl)


def supported(rt: Runtime) -> bool:
    """Whether the device runs the passes: they decide in double precision, as numpy."""
    return rt.fp64 and groups.NEIGHBOURS <= REACH_MAX


def times_up(times: pairing.Times, passes: bool = True) -> tuple:
    """What the device reads of `times`: with the passes there (`track`), the pairs'
    centres and half gaps (s) and their groups' bounds; where the pairs are in groups,
    each group's first pair (int32: plain transforms pair rows within a group,
    kernels/fft.cl)."""
    up = (times.mid, times.half_gap, times.bounds) if passes else ()
    return up if times.groups is None else (*up, np.asarray(times.groups, np.int32))


def times_down(buffers: list, times: pairing.Times, passes: bool = True) -> tuple[list, pairing.Times]:
    """The device copies of `times_up(times, passes)` off the end of `buffers`: the
    buffers before them, and `times` holding them (Times.device, None where not up)."""
    n = len(times_up(times, passes))
    if n == 0:
        return list(buffers), times
    got = list(buffers[len(buffers) - n:])
    device = (*(got[:3] if passes else (None,) * 3), got[-1] if times.groups is not None else None)
    return list(buffers[:len(buffers) - n]), replace(times, device=device)


def track(rt: Runtime, bufs: Buffers, rows: tuple[DeviceRows, DeviceRows], times: pairing.Times,
          model: doppler.DopplerModel, search: Search, iterations: int, riders: tuple = (),
          meanwhile: Callable[[], None] | None = None) -> tuple[list, pairing.Passes]:
    """The plain pass of both directions (every echo with `search.echoes`) and up to
    `iterations` de-chirp passes, each regularising the velocities and re-measuring the
    pairs whose de-chirp velocity moved (the passes stop on the device when none did).
    One copy goes up, the pairs' times and groups (none where `times.device` holds them),
    and one comes down (the plain pass's results, the tracker's state and its verdict, and
    `riders`: buffers.Rider, other steps' results). `meanwhile`: host work run once the
    passes and that download are queued, before it is waited for.

    Returns
    -------
    first : measure_each's results of the plain pass, (Peaks, None, Detections or None)
        per direction.
    state : the tracker's state after the passes, with its verdict (pairing.verdict).
    """
    pairs = rows[0].shape[0]
    plain = [(x, None, None) for x in rows]
    head = k_spectrum.parts(plain, pairs, model.nfft, search.echoes)
    out = Packed(bufs, "tracked", [*head, *_state_parts(pairs), _phasor_part(pairs)], riders)
    times = _times_here(bufs, times)
    band = (model.nfft, search.lo, search.hi)
    bands = k_spectrum.band_buffers(bufs, search)
    k_spectrum.measure_each(rt, bufs, plain, None, *band, echoes=search.echoes, out=out, groups=times.groups,
                            d_groups=times.device[3], bands=bands)
    dechirp = [(rows[0], model.beta_rise, None), (rows[1], model.beta_fall, None)]
    again = Packed(bufs, "track_pass", k_spectrum.parts(dechirp, pairs, model.nfft))
    seed = seeded = None
    if search.velocity is not None:     # the first pass de-chirped at each pair's course velocity
        seeded = Packed(bufs, "track_seeded", k_spectrum.parts(dechirp, pairs, model.nfft))
        seed = _at_course(rt, bufs, dechirp, search, band, bands, seeded)
    run = _Passes(rt, bufs, pairs, times, model, search.reach, out.buffers[len(head):-1], seed=seed)
    for it in range(iterations):
        # each direction's peaks: parts 0, 1 and 6, 7
        got = (again if it else out if seeded is None else seeded).buffers
        run.launch(it, iterations, [got[i] for i in (0, 1, 6, 7)])
        k_spectrum.measure_each(rt, bufs, dechirp, None, *band, picked=run.listed, listed=run.state,
                                out=again, bands=bands)
    run.launch(iterations, iterations, [again.buffers[i] for i in (0, 1, 6, 7)])
    run.verdict()
    k_phase.launch_state(rt, bufs, rows, model, run.vel, run.d_r, run.d_f, out.buffers[-1])
    views = out.download(meanwhile)
    first = k_spectrum.results(views[: len(head)], plain, pairs, model.nfft, search.echoes)
    return first, _passes(views[len(head):-1], np.ones(pairs, np.int32), 1, views[-1])


def integrated(rt: Runtime, bufs: Buffers, rows: tuple[DeviceRows, DeviceRows], times: pairing.Times,
               model: doppler.DopplerModel, search: Search, iterations: int, k: int, riders: tuple = ()
               ) -> pairing.Passes:
    """The tracker's passes on K-window integrated spectra (twin: pairing.passes with
    k > 1): the power spectra of both directions kept on the device, each pass the
    moved pairs' spectra made again at their de-chirp velocity, the displacement along
    the track, every pair's integrated peak, the regularisation; the verdict after the
    last. One copy comes down: the state, the counts of spectra and the verdict (with
    `riders`); the pairs' times go up where `times.device` lacks them."""
    pairs = rows[0].shape[0]
    half = model.nfft // 2
    out = Packed(bufs, "integrated_state", [*_state_parts(pairs), (np.int32, pairs), _phasor_part(pairs)],
                 riders)
    times = _times_here(bufs, times)
    d_bounds = times.device[2]
    stores = [DeviceRows(bufs, pairs, half) for _ in rows]
    band = (model.nfft, search.lo, search.hi)
    bands = k_spectrum.band_buffers(bufs, search)
    dechirp = [(x, beta, store) for x, beta, store in zip(rows, (model.beta_rise, model.beta_fall), stores,
                                                          strict=True)]
    seed = None
    if search.velocity is None:
        k_spectrum.measure_each(rt, bufs, [(x, None, store) for x, store in zip(rows, stores, strict=True)],
                                None, *band)
    else:               # every spectrum first de-chirped at its pair's course velocity
        seed = _at_course(rt, bufs, dechirp, search, band)
    # each direction's (bin, SNR, count): the falling one's counts (the same) come down
    got = Packed(bufs, "integrated_peaks", [(np.float32, pairs), (np.float32, pairs), (np.int32, pairs)] * 2
                 ).buffers[:5] + out.buffers[-2:-1]
    jobs = [(stores[0], *got[:3]), (stores[1], *got[3:])]
    measured = [got[0], got[1], got[3], got[4]]
    disp = bufs.get("track_disp", 4 * pairs)
    run = _Passes(rt, bufs, pairs, times, model, search.reach, out.buffers[:-2],
                  (got[5], bufs.constant("floors", floors(k), np.float64), disp), seed)
    rt.kernel("track", "track_start")(rt.queue, *rt.items(pairs), np.int32(pairs), run.vd, disp, run.state)
    if search.velocity is not None:     # ... read at the displacement of those velocities
        rt.copy(disp, pairing.displacement_bins(times.mid, times.groups, search.velocity,
                                                model.metres_per_bin).astype(np.float32))
    k_integrate.launch(rt, bufs, jobs, disp, d_bounds, k, search, run.state, bands)
    for it in range(iterations):
        run.launch(it, iterations, measured)       # the displacement of the moved velocities too
        k_spectrum.measure_each(rt, bufs, dechirp, None, *band, picked=run.listed, listed=run.state)
        k_integrate.launch(rt, bufs, jobs, disp, d_bounds, k, search, run.state, bands)
    run.launch(iterations, iterations, measured)
    run.verdict()
    k_phase.launch_state(rt, bufs, rows, model, run.vel, run.d_r, run.d_f, out.buffers[-1])
    views = out.download()
    return _passes(views[:-2], views[-2].copy(), k, views[-1])


def _at_course(rt: Runtime, bufs: Buffers, jobs: list, search: Search, band: tuple,
               bands: tuple | None = None, out: Packed | None = None):
    """spectrum.measure_each of `jobs` (each direction's (rows, beta, store)) de-chirped
    at each pair's course velocity (Search.velocity), in `band` (nfft, lo, hi) and
    `bands`, into `out`: the passes' first measurement. Returns the velocities' device
    buffer (float32), the passes' `seed`."""
    seed = bufs.upload("track_seed", np.asarray(search.velocity, np.float32))
    k_spectrum.measure_each(rt, bufs, jobs, search.velocity, *band, out=out, bands=bands,
                            picked=(bufs.constant("index0", k_spectrum.zeros(1), np.int32), seed))
    return seed


def _state_parts(pairs: int) -> list[tuple]:
    """The parts of the tracker's state and verdict in its download: d_r s_r d_f s_f vd,
    then valid and the residuals."""
    f64, f32, i32 = np.float64, np.float32, np.int32
    return [(f64, pairs), (f32, pairs), (f64, pairs), (f32, pairs), (f64, pairs), (i32, pairs), (f64, pairs)]


def _phasor_part(pairs: int) -> tuple:
    """The phasors' part of a download (kernels/phase.cl `peak_phasor_state`)."""
    return (np.float32, 4 * pairs)


def _passes(views: list, count: np.ndarray, k: int, phasors: np.ndarray) -> pairing.Passes:
    """pairing.Passes from the downloaded parts of `_state_parts` and the phasors."""
    *state, valid, resid = (v.copy() for v in views)
    return pairing.Passes(*state, count, k, verdict=(valid.astype(bool), resid),
                          phasors=tuple(k_phase.complex_pairs(phasors)))


@functools.lru_cache(maxsize=4)
def floors(k: int) -> np.ndarray:
    """The SNR floor (dB) of a peak integrated over c spectra, at index c <= k
    (integrate.threshold_db; kernels/track.cl's `heard`); one object per k."""
    out = np.full(k + 1, np.inf)
    out[1:] = integrate.threshold_db(np.arange(1, k + 1), pairing.SNR_MIN_DB)
    out.flags.writeable = False
    return out


def _times_here(bufs: Buffers, times: pairing.Times) -> pairing.Times:
    """`times` with its device copies (times_up), uploaded where it lacks them."""
    if times.device is None or times.device[0] is None:
        up = times_up(times)
        _, times = times_down(Packed(bufs, "track_times", [(a.dtype, a.size) for a in up]).upload(*up), times)
    return times


class _Passes:
    """kernels/track.cl's passes over `pairs` (their velocity median over `reach`,
    Search.reach) and their verdict, into the device buffers `state` (`_state_parts`),
    the first from the de-chirp velocities `seed` (a device buffer of float32; None: 0);
    `counted`, with integration: the measurements' counts of spectra, the floors by
    count and the displacement (device buffers; None: every peak heard over
    SNR_MIN_DB, the measurements the pairs listed)."""

    def __init__(self, rt: Runtime, bufs: Buffers, pairs: int, times: pairing.Times,
                 model: doppler.DopplerModel, reach: int, state: list, counted: tuple | None = None,
                 seed=None) -> None:
        self.rt, self.pairs, self.times, self.model, self.reach = rt, pairs, times, model, reach
        # the first pass's de-chirp velocities (float32, Search.velocity; None: 0 m/s)
        self.seed = ((bufs.constant("v0", k_spectrum.zeros(1)), np.int32(0)) if seed is None
                     else (seed, np.int32(1)))
        self.d_r, self.s_r, self.d_f, self.s_f, self.vd, self.valid, self.resid = state
        self.state = bufs.get("track_state", 8)   # [pairs listed, passes stopped]: the first pass sets
        self.vel, self.med, self.nxt = (bufs.get(f"track_{n}", 8 * pairs) for n in ("vel", "med", "next"))
        self.trusted, self.prev, self.slot, rows, v32 = (bufs.get(f"track_{n}", 4 * pairs)
                                                         for n in ("trusted", "prev", "slot", "rows", "v32"))
        self.listed = (rows, v32)
        self.vouched = bufs.get("track_vouched", 4 * pairs)
        self.dist = bufs.get("track_dist", 8 * pairs)
        self.every = counted is not None        # integrated: every pair measured each pass
        if counted is None:
            none = bufs.constant("index0", k_spectrum.zeros(1), np.int32)
            counted = (none, bufs.constant("floors1", k_spectrum.zeros(1), np.float64), none)
        # the counts of spectra, the floors by count, whether counted; the displacement
        self.counted, self.disp = (*counted[:2], np.int32(self.every)), counted[2]
        self.kernel = rt.kernel("track", "track_pass")
        # PoCL: one item loops without barriers' cost; elsewhere at most what the kernel's
        # registers allow (its median window is 33 doubles an item)
        self.lsz = 1 if rt.lanes else min(rt.group_size(16, 256), self.kernel.kernel.get_work_group_info(
            cl.kernel_work_group_info.WORK_GROUP_SIZE, rt.device))

    def launch(self, it: int, iterations: int, measured: list) -> None:
        """Pass `it` of `iterations` (the last: the state and median for the verdict),
        reading the peaks `measured` (bin and SNR of each direction: device buffers);
        integrated, it writes the displacement of the new velocities too."""
        i32, f32, f64 = np.int32, np.float32, np.float64
        m, lsz = self.model, self.lsz
        d_mid, d_half, d_bounds, _ = self.times.device
        self.kernel(self.rt.queue, (lsz,), (lsz,), i32(self.pairs), i32(it == 0), i32(it == iterations),
                    i32(self.every), *measured, self.slot, f64(m.metres_per_bin), d_mid, d_half, d_bounds,
                    f64(m.k_rise), f64(m.k_fall), self.d_r, self.d_f, self.s_r, self.s_f, self.vd, *self.seed,
                    i32(self.reach), f32(pairing.SNR_MIN_DB), *self.counted,
                    f64(verification.CONSISTENT_MPS), f64(pairing.PLAIN_SHARE if it == 0 else 0.0),
                    f64(pairing.STOP_MPS), self.vel, self.med,
                    self.nxt, self.trusted, self.prev, *self.listed, self.state, self.disp,
                    cl.LocalMemory(16 * lsz), cl.LocalMemory(8 * lsz))

    def verdict(self) -> None:
        """pairing.verdict after the last pass: one work-item a pair."""
        i32, f32, f64 = np.int32, np.float32, np.float64
        m, pairs = self.model, self.pairs
        d_mid, d_half, d_bounds, _ = self.times.device
        dist = self.dist
        self.rt.kernel("track", "track_valid")(
            self.rt.queue, *self.rt.items(pairs), i32(pairs), self.d_r, self.d_f, self.s_r, self.s_f, self.vd,
            d_half, self.vel, self.med, f64(m.k_rise), f64(m.k_fall), f32(pairing.SNR_MIN_DB), *self.counted,
            f64(pairing.CONVERGED_MPS), f64(verification.CONSISTENT_MPS), dist, self.valid)
        residuals(self.rt, pairs, d_mid, d_bounds, dist, self.vel, self.valid, self.resid, self.vouched)


def residuals(rt: Runtime, pairs: int, t, bounds, dist, vel, valid, resid, vouched) -> None:
    """Launch kernels/track.cl's `track_residual` (twin: verification._residuals): each pair's
    continuity residual (m, into `resid`) against the `valid` pairs of its group
    (`bounds`, group_bounds) and how many vouch for it (into `vouched`); `t`, `dist`,
    `vel`: the pairs' centres (s), distances (m), velocities (m/s). Device buffers."""
    i32 = np.int32
    rt.kernel("track", "track_residual")(rt.queue, *rt.items(pairs), i32(pairs), i32(groups.NEIGHBOURS),
                                         i32(verification.SUPPORT), t, bounds, dist, vel, valid, resid,
                                         vouched)
