"""Where a braking body comes to rest: the forecast that joins a mover to its rest.

A body in motion whose acceleration stands against its motion (BRAKE_MPS2 per m/s of its
speed or more) stops v^2 / 2|a| ahead of where it was last seen. A fixed object first
seen there soon after is that body at rest (fmcw_cl.meeting joins the two), and a body
moving off the other way across the same gap is not its motion going on
(fmcw_cl.course_bodies carries no course onto it). Time reversed, the same forecast
tells a body that set off from a rest.
"""

from __future__ import annotations

import numpy as np

from .stages import bank

MOVING_MPS = bank.MIN_MPS   # ends this fast: a body in motion, never two at rest side by side
REST_GAP_S = 0.05           # a body may rest this long unseen after its last pair in motion
BRAKE_MPS2 = 10.0           # an end's acceleration this strong against (or with) its motion is braking
REST_M = 3e-3               # the rest within this, or REST_SHARE of the way, of where the braking ends it
REST_SHARE = 0.3


def comes_to_rest(end: tuple, rest_m: float, dt: float) -> bool:
    """Whether a body in motion at `end` (index, t, d, v, acc; its acceleration taken
    against its motion: a mover's last pair, or a set-off's first with time reversed)
    comes to rest at `rest_m` (m) within `dt` (s): braking, the rest ahead of it within
    REST_M or REST_SHARE of where its braking ends it (a glide's braking eases as it
    comes to rest: 8.0 and 10.0 mm forecast, 10.1 and 11.7 mm), in time at the least
    braking that stops it there (2 s / |v|)."""
    v, acc = end[3], end[4]
    ahead = (rest_m - end[2]) * np.sign(v)
    if abs(v) < MOVING_MPS or acc * v > -BRAKE_MPS2 * abs(v) or ahead <= 0 or not 0 < dt <= REST_GAP_S:
        return False
    stop = v * v / (2.0 * abs(acc))
    return bool(abs(ahead - stop) <= max(REST_M, REST_SHARE * stop) and 2.0 * ahead / abs(v) <= dt)


def set_off_from(end: tuple, rest_m: float, dt: float) -> bool:
    """Whether a body in motion at `end` (index, t, d, v, acc: a set-off's first pair)
    set off from rest at `rest_m` (m) within `dt` (s) before: `comes_to_rest` with time
    reversed (a set-off is a rest come to backwards)."""
    return comes_to_rest((end[0], -end[1], end[2], -end[3], end[4]), rest_m, dt)
