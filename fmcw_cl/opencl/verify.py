"""Launcher of the verification's tests on the device (twins: fmcw_cl.stages.pairing's
`disagreed`, kernels/verify.cl, and `_residuals` over one group, kernels/track.cl):
the pairs of a whole track go up by one copy and each test's verdicts come down by one."""

from __future__ import annotations

import numpy as np

from ..stages import pairing
from . import track as k_track
from .buffers import Buffers, Packed
from .context import Runtime

# fewer pairs are tested on the host: a trip each way costs more than their tests there
# (a second look's stretches of 240 pairs; a 0.3 s track of 6000 pairs: 3.8 ms of host
# CPU in numpy, 1.0 ms with the tests on the 2-core PoCL)
PAIRS_MIN = 4096


def _up(bufs: Buffers, t: np.ndarray, dist: np.ndarray, vel: np.ndarray, ok: np.ndarray,
        *more: np.ndarray) -> list:
    """The pairs' times (s), distances (m), velocities (m/s), flags and `more` on the
    device, by one copy."""
    arrays = [np.asarray(a, np.float64) for a in (t, dist, vel)] + [np.asarray(ok, np.int32), *more]
    return Packed(bufs, "verify_in", [(a.dtype, a.size) for a in arrays]).upload(*arrays)


def disagreed(rt: Runtime, bufs: Buffers, t: np.ndarray, dist: np.ndarray, vel: np.ndarray,
              ok: np.ndarray) -> np.ndarray:
    """Twin: pairing.disagreed."""
    n = t.size
    d_t, d_dist, d_vel, d_ok = _up(bufs, t, dist, vel, ok)
    out = Packed(bufs, "verify_drop", [(np.int32, n)])
    if n:
        f64 = np.float64
        rt.kernel("verify", "kinematic_drop")(
            rt.queue, *rt.items(n), np.int32(n), np.int32(pairing.KINEMATIC_PAIRS), f64(pairing.KINEMATIC_S),
            f64(pairing.JUMP_MAX_M), f64(pairing.ACCEL_MAX), f64(pairing.CONSISTENT_MPS), d_t, d_dist, d_vel,
            d_ok, out.buffers[0])
    return out.download()[0].astype(bool)


def residuals(rt: Runtime, bufs: Buffers, t: np.ndarray, dist: np.ndarray, vel: np.ndarray,
              trusted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Twin: pairing._residuals of every pair, in one group."""
    n = t.size
    d_t, d_dist, d_vel, d_ok, d_bounds = _up(bufs, t, dist, vel, trusted, pairing.group_bounds(None, n))
    out = Packed(bufs, "verify_resid", [(np.float64, n), (np.int32, n)])
    if n:
        k_track.residuals(rt, n, d_t, d_bounds, d_dist, d_vel, d_ok, *out.buffers)
    resid, support = out.download()
    return resid.copy(), support.copy()
