"""Launcher of kernels/track.cl: the tracker's plain pass and de-chirp passes with the
regularisation between them on the device, and the pairs' verdict after them (twin:
fmcw_cl.stages.pairing.SpectrumOps.track, its `passes` without integration, and
pairing.verdict)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..stages import pairing
from ..stages.spectrum import Search
from . import spectrum as k_spectrum
from .buffers import Buffers, DeviceRows, Packed
from .context import Runtime, cl

REACH_MAX = 16      # the running median's half-width the kernel holds (kernels/track.cl)


def supported(rt: Runtime) -> bool:
    """Whether the device runs the passes: they decide in double precision, as numpy."""
    return rt.fp64 and pairing.NEIGHBOURS <= REACH_MAX


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
          model: pairing.DopplerModel, search: Search, iterations: int, riders: tuple = ()
          ) -> tuple[list, pairing.Passes]:
    """The plain pass of both directions (every echo with `search.echoes`) and up to
    `iterations` de-chirp passes, each regularising the velocities and re-measuring the
    pairs whose de-chirp velocity moved (the passes stop on the device when none did).
    One copy goes up, the pairs' times and groups (none where `times.device` holds them),
    and one comes down (the plain pass's results, the tracker's state and its verdict, and
    `riders`: buffers.Rider, other steps' results).

    Returns
    -------
    first : measure_each's results of the plain pass, (Peaks, None, Detections or None)
        per direction.
    state : the tracker's state after the passes, with its verdict (pairing.verdict).
    """
    pairs = rows[0].shape[0]
    f64, f32, i32 = np.float64, np.float32, np.int32
    plain = [(x, None, None) for x in rows]
    head = k_spectrum.parts(plain, pairs, model.nfft, search.echoes)
    state = [(f64, pairs), (f32, pairs), (f64, pairs), (f32, pairs), (f64, pairs)]   # d_r s_r d_f s_f vd
    judged = [(i32, pairs), (f64, pairs)]                                             # valid, residuals
    out = Packed(bufs, "tracked", [*head, *state, *judged], riders)
    d_r, s_r, d_f, s_f, vd, valid, resid = out.buffers[len(head):]
    if times.device is None or times.device[0] is None:
        up = times_up(times)
        _, times = times_down(Packed(bufs, "track_times", [(a.dtype, a.size) for a in up]).upload(*up), times)
    d_mid, d_half, d_bounds, d_groups = times.device
    d_state = bufs.get("track_state", 8)          # [pairs listed, passes stopped]: the first pass sets
    vel, med, nxt = (bufs.get(f"track_{n}", 8 * pairs) for n in ("vel", "med", "next"))
    trusted, prev, slot, listed, v32 = (bufs.get(f"track_{n}", 4 * pairs)
                                        for n in ("trusted", "prev", "slot", "rows", "v32"))
    band = (model.nfft, search.lo, search.hi)
    k_spectrum.measure_each(rt, bufs, plain, None, *band, echoes=search.echoes, out=out, groups=times.groups,
                            d_groups=d_groups)
    dechirp = [(rows[0], model.beta_rise, None), (rows[1], model.beta_fall, None)]
    again = Packed(bufs, "track_pass", k_spectrum.parts(dechirp, pairs, model.nfft))
    kernel = rt.kernel("track", "track_pass")
    # PoCL: one item loops without barriers' cost; elsewhere at most what the kernel's
    # registers allow (its median window is 33 doubles an item)
    lsz = 1 if rt.lanes else min(rt.group_size(16, 256), kernel.kernel.get_work_group_info(
        cl.kernel_work_group_info.WORK_GROUP_SIZE, rt.device))

    def launch(it: int) -> None:
        got = (out if it == 0 else again).buffers      # each direction's peaks: parts 0, 1 and 6, 7
        kernel(rt.queue, (lsz,), (lsz,), i32(pairs), i32(it == 0), i32(it == iterations),
               *(got[i] for i in (0, 1, 6, 7)), slot, f64(model.metres_per_bin), d_mid, d_half, d_bounds,
               f64(model.k_rise), f64(model.k_fall), d_r, d_f, s_r, s_f, vd, i32(pairing.NEIGHBOURS),
               f32(pairing.SNR_MIN_DB), f64(pairing.CONSISTENT_MPS),
               f64(pairing.PLAIN_SHARE if it == 0 else 0.0), f64(pairing.STOP_MPS), vel, med, nxt, trusted,
               prev, listed, v32, d_state, cl.LocalMemory(12 * lsz))

    for it in range(iterations):
        launch(it)
        k_spectrum.measure_each(rt, bufs, dechirp, None, *band, picked=(listed, v32), listed=d_state,
                                out=again)
    launch(iterations)
    # the verdict (pairing.verdict): one work-item a pair
    dist = bufs.get("track_dist", 8 * pairs)
    rt.kernel("track", "track_valid")(
        rt.queue, *rt.items(pairs), i32(pairs), d_r, d_f, s_r, s_f, vd, d_half, vel, med, f64(model.k_rise),
        f64(model.k_fall), f32(pairing.SNR_MIN_DB), f64(pairing.CONVERGED_MPS), f64(pairing.CONSISTENT_MPS),
        dist, valid)
    residuals(rt, pairs, d_mid, d_bounds, dist, vel, valid, resid, bufs.get("track_vouched", 4 * pairs))
    views = out.download()
    first = k_spectrum.results(views[: len(head)], plain, pairs, model.nfft, search.echoes)
    *state, valid, resid = (v.copy() for v in views[len(head):])
    return first, pairing.Passes(*state, np.ones(pairs, np.int32), verdict=(valid.astype(bool), resid))


def residuals(rt: Runtime, pairs: int, t, bounds, dist, vel, valid, resid, vouched) -> None:
    """Launch kernels/track.cl's `track_residual` (twin: pairing._residuals): each pair's
    continuity residual (m, into `resid`) against the `valid` pairs of its group
    (`bounds`, group_bounds) and how many vouch for it (into `vouched`); `t`, `dist`,
    `vel`: the pairs' centres (s), distances (m), velocities (m/s). Device buffers."""
    i32 = np.int32
    rt.kernel("track", "track_residual")(rt.queue, *rt.items(pairs), i32(pairs), i32(pairing.NEIGHBOURS),
                                         i32(pairing.SUPPORT), t, bounds, dist, vel, valid, resid, vouched)
