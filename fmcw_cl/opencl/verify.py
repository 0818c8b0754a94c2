"""Launcher of the verification's tests on the device (twins: fmcw_cl.stages.verification's
`disagreed`, kernels/verify.cl, and `_residuals` over one group, kernels/track.cl):
the pairs of a whole track go up by one copy and each test's verdicts come down by one."""

from __future__ import annotations

import numpy as np

from ..stages import groups, verification
from . import track as k_track
from .buffers import Buffers, Packed
from .context import Runtime

# fewer pairs are tested on the host, where a trip each way would cost more than their
# tests: numpy's test of motion loops over 48 neighbours whatever the count (2-core PoCL,
# 250 pairs: 0.59 ms of host CPU, on the device 0.03 ms and 0.10 of wall; 2000 pairs:
# 1.0 ms, on the device 0.03 and 0.39; the residuals at 250 pairs 0.11 ms, 0.05 and 0.11)
PAIRS_MIN = 128


def _up(bufs: Buffers, t: np.ndarray, dist: np.ndarray, vel: np.ndarray, ok: np.ndarray,
        *more: np.ndarray) -> list:
    """The pairs' times (s), distances (m), velocities (m/s), flags and `more` on the
    device, by one copy."""
    arrays = [np.asarray(a, np.float64) for a in (t, dist, vel)] + [np.asarray(ok, np.int32), *more]
    return Packed(bufs, "verify_in", [(a.dtype, a.size) for a in arrays]).upload(*arrays)


def disagreed(rt: Runtime, bufs: Buffers, t: np.ndarray, dist: np.ndarray, vel: np.ndarray,
              ok: np.ndarray) -> np.ndarray:
    """Twin: verification.disagreed."""
    n = t.size
    d_t, d_dist, d_vel, d_ok = _up(bufs, t, dist, vel, ok)
    out = Packed(bufs, "verify_drop", [(np.int32, n)])
    if n:
        f64 = np.float64
        rt.kernel("verify", "kinematic_drop")(
            rt.queue, *rt.items(n), np.int32(n), np.int32(verification.KINEMATIC_PAIRS),
            f64(verification.KINEMATIC_S), f64(verification.JUMP_MAX_M), f64(verification.ACCEL_MAX),
            f64(verification.CONSISTENT_MPS), d_t, d_dist, d_vel, d_ok, out.buffers[0])
    return out.download()[0].astype(bool)


def residuals(rt: Runtime, bufs: Buffers, t: np.ndarray, dist: np.ndarray, vel: np.ndarray,
              trusted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Twin: verification._residuals of every pair, in one group."""
    n = t.size
    d_t, d_dist, d_vel, d_ok, d_bounds = _up(bufs, t, dist, vel, trusted, groups.group_bounds(None, n))
    out = Packed(bufs, "verify_resid", [(np.float64, n), (np.int32, n)])
    if n:
        k_track.residuals(rt, n, d_t, d_bounds, d_dist, d_vel, d_ok, *out.buffers)
    resid, support = out.download()
    return resid.copy(), support.copy()
