"""One candidate's track: how many bodies made its verified pairs.

The tables showed one candidate, and its tracker followed one echo at a time: where it
passed from one body to another (two sways crossing in one span, a hand moved down
through a jump's path) its parts of BODY_PAIRS verified pairs or more are told apart
(identities.parted, .rejoined); beside one such body, the brief parts it passed onto at
once are another echo's.
"""

from __future__ import annotations

import numpy as np

from . import identities, objects
from .handovers import Asked
from .track import Track

# a part of a track this many verified pairs long (2 ms: fixed_echoes.TOGETHER_S) is a body's
BODY_PAIRS = 40


def one_body(track: Track, moving: bool) -> Track:
    """`track`, the one object of its scene, where one body can have made its verified
    pairs; else (they make BODY_PAIRS or more of two bodies or more, identities.parted
    and .rejoined: two movers whose spans overlap in range, the tracker passing from one
    to the other where they come near) a copy with all of them `ambiguous`. Two sways
    crossing in one span, one object: 1167 valid pairs on the other sway; a hand moved
    down through a jump's path: 2109. Beside one body, parts its tracker passed onto at
    once are another echo's (`_passed_onto`)."""
    bodies, body = count(track, moving)
    if bodies < 2:
        return body
    out = objects.invalidated(track, track.valid.copy())
    out.attrs["target_choice"] = (f"{track.attrs.get('target_choice', '')}: its verified pairs are two "
                                  "bodies or more (no one body moves between them): cannot be told apart")
    return out


def count(track: Track, moving: bool) -> tuple[int, Track]:
    """How many parts of BODY_PAIRS verified pairs or more `track` holds, one body's
    each (identities.parted and .rejoined), and beside one such, `track` with the parts
    its tracker passed onto at once `ambiguous` (`_passed_onto`)."""
    asked = Asked()             # the track's handovers read once for both
    parts = identities.rejoined(identities.parted([objects.SceneObject(1, moving, track, "")], asked=asked),
                                asked=asked)
    big = [int(p.track.valid.sum()) >= BODY_PAIRS for p in parts]
    if sum(big) != 1:
        return sum(big), track
    return 1, _passed_onto(track, [p.track for p, b in zip(parts, big, strict=True) if not b], asked(track))


def _passed_onto(track: Track, small: list[Track], handed: tuple[np.ndarray, np.ndarray]) -> Track:
    """`track` with the verified pairs of its `small` parts (beside one of BODY_PAIRS or
    more) `ambiguous` where the tracker passed onto such a part or off it at once
    (`handed`: the handovers' times before and after): another echo's, there while the
    body was elsewhere. Two legs landing 5 mm apart: the tracker left the one for the
    other for 2 ms and came back, 39 valid pairs of the other (movers.py seed 20,
    capture 30)."""
    before, after = handed
    taken = np.zeros(track.pairs, bool)
    for p in small:
        t = p.time_s[p.valid]
        if t.size and (np.isin(t[0], after) or np.isin(t[-1], before)):
            taken |= p.valid
    return objects.invalidated(track, taken) if taken.any() else track
