"""Scenes of several objects, each with its own trajectory and visibility.

A lab's scene holds more than the target: a second limb or a cable that sways, a hand
put into the beam, something that passes in front of the target, a wall the target
passes. Each scene here is the project's kind of capture at a lab's SNR (0 dB per
sample at 0.3 m, speckle of 3 ms) with the truth of every echo written
(`Capture.truth_objects`). `write(name, path, seed)` makes one.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .scene import Trajectory, glide, jump, rail, static, sway
from .writer import Mover, SimulationConfig, simulate_capture

TARGET_CODES = 500.0   # the target's amplitude at 0.3 m (SimulationConfig's 1500 codes at 0.1 m, 1/R)


@dataclass(frozen=True)
class Scene:
    """A capture of several objects: the target's trajectory, the capture's span in it
    (start, duration s) and the instrument with the other objects."""

    trajectory: Trajectory
    start_s: float
    duration_s: float
    config: SimulationConfig


LAB_SCENE = SimulationConfig(snr_db=0.0, speckle_s=3e-3)


def _jump_and_sway(codes: float) -> Scene:
    return Scene(jump(0.3), 0.0, 0.3, replace(LAB_SCENE, movers=(Mover(sway(0.3), codes),)))


def _rail_through_sway() -> Scene:
    # the rail's start (0.06 -> 0.38 m from 50 ms) passes an object swaying at 0.25 m
    swaying = Mover(sway(0.2, 0.25, 0.01, 3.0), 400.0)
    return Scene(rail(0.2), 0.0, 0.2, replace(LAB_SCENE, movers=(swaying,)))


def _two_sways_crossing() -> Scene:
    # two objects swaying over overlapping spans (0.15-0.25 and 0.17-0.27 m, 4 and 3 Hz):
    # their ranges cross a few times a period, within a millimetre at some crossings
    other = Mover(sway(0.3, 0.22, 0.05, 3.0, 1.0), 400.0)
    return Scene(sway(0.3, 0.20, 0.05, 4.0), 0.0, 0.3, replace(LAB_SCENE, movers=(other,)))


def _hand_through_jump() -> Scene:
    # a hand moved down from 0.32 to 0.05 m (50-250 ms) through the jumping foot's path
    hand = Mover(glide(0.3, 0.32, 0.05, 0.05, 0.25), 600.0)
    return Scene(jump(0.3), 0.0, 0.3, replace(LAB_SCENE, movers=(hand,)))


def _two_legs() -> Scene:
    # a second leg: the same jump 40 ms ahead, 1 dB stronger; the feet's ranges cross
    # as one lifts while the other lands
    ahead = jump(0.34)

    def at(t, k):
        return ahead.at(np.asarray(t) + 0.04)[k]

    leg = Trajectory.from_velocity(0.0, 0.3, lambda t: at(t, 1), lambda t: at(t, 2), float(ahead.at(0.04)[0]))
    return Scene(jump(0.3), 0.0, 0.3, replace(LAB_SCENE, movers=(Mover(leg, 560.0),)))


def _rail_against_glide() -> Scene:
    # the rail's start (0.06 -> 0.38 m) and an object moved the other way (0.36 -> 0.08 m)
    towards = Mover(glide(0.25, 0.36, 0.08, 0.05, 0.20), 800.0)
    return Scene(rail(0.25), 0.0, 0.25, replace(LAB_SCENE, movers=(towards,)))


def _glide_through_sway() -> Scene:
    # an object swaying 0.19 +- 0.04 m at 4.9 Hz and one glided 0.08 -> 0.38 m through it
    # (an outside hunt's draw, seed 1049): the tracker passes between them, 39 mm in 0.2 ms
    glided = Mover(glide(0.7, 0.0763, 0.3821, 0.1882, 0.3525), 603.0)
    swaying = sway(0.7, 0.1939, 0.0374, 4.8885, 4.5844)
    return Scene(swaying, 0.2258, 0.168, replace(LAB_SCENE, movers=(glided,)))


def _hand_over_rest() -> Scene:
    # a target at rest at 0.30 m; a hand moves in the beam (0.20 -> 0.17 m) for 30 ms
    hand = Mover(glide(0.1, 0.20, 0.17, 0.03, 0.06), 1000.0, ((0.0, 0.03), (0.06, 0.1)))
    return Scene(static(0.1, 0.30), 0.0, 0.1,
                 replace(LAB_SCENE, movers=(hand,), target_hidden=((0.03, 0.06),)))


def _occlusion(shift_m: float) -> Scene:
    # something passes 0.15 m in front of a target at rest for 8 ms; the target returns
    # where it was, or shift_m further (moved while hidden)
    hidden = ((0.020, 0.028),)
    front = Mover(glide(0.05, 0.16, 0.14, 0.019, 0.029), 800.0, ((0.0, 0.019), (0.029, 0.05)))
    return Scene(glide(0.05, 0.30, 0.30 + shift_m, 0.021, 0.027), 0.0, 0.05,
                 replace(LAB_SCENE, movers=(front,), target_hidden=hidden))


def _through_wall() -> Scene:
    wall = replace(LAB_SCENE, reflectors=((0.25, 800.0),))
    return Scene(glide(0.2, 0.10, 0.40, 0.02, 0.18), 0.0, 0.2, wall)


def _through_trembling_wall() -> Scene:
    # the wall trembles 1 um at 50 Hz (a pane, a cable): its phase swings +-8 rad, so
    # rows without still echoes keep it (fmcw_cl.stages.clutter)
    wall = replace(LAB_SCENE, movers=(Mover(sway(0.2, 0.25, 1e-6, 50.0), 800.0),))
    return Scene(glide(0.2, 0.10, 0.40, 0.02, 0.18), 0.0, 0.2, wall)


def _foot_at_window() -> Scene:
    return Scene(jump(0.3, ground_m=0.05), 0.0, 0.3, replace(LAB_SCENE, reflectors=((0.05, 1200.0),)))


def _slow_plateau() -> Scene:
    # 15 ms of the jump slowing near its first plateau, nothing else in view, clean
    return Scene(jump(0.3), 0.095, 0.015, SimulationConfig())


SCENES = {
    "jump + sway 6 dB weaker": lambda: _jump_and_sway(250.0),
    "jump + sway 6 dB stronger": lambda: _jump_and_sway(1000.0),
    "rail crossing a sway": _rail_through_sway,
    "two sways crossing": _two_sways_crossing,
    "hand down through a jump": _hand_through_jump,
    "rail against a glide": _rail_against_glide,
    "two legs, 40 ms apart": _two_legs,
    "glide through a sway": _glide_through_sway,
    "hand over a target at rest": _hand_over_rest,
    "occlusion, same place": lambda: _occlusion(0.0),
    "occlusion, 30 mm further": lambda: _occlusion(0.03),
    "target through a wall": _through_wall,
    "target through a trembling wall": _through_trembling_wall,
    "foot at a window": _foot_at_window,
    "slow plateau, 15 ms": _slow_plateau,
    "jump + static": lambda: Scene(jump(0.3), 0.0, 0.3,
                                   replace(LAB_SCENE, movers=(Mover(static(0.3, 0.45), 500.0),))),
}


def write(name: str, path, seed: int) -> dict:
    """Write scene `name` (SCENES) to `path` with `seed`; the simulator's hidden draws."""
    s = SCENES[name]()
    return simulate_capture(path, s.trajectory, s.duration_s, seed, s.config, start_s=s.start_s)
