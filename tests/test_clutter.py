"""The still echoes taken out of the resampled half-sweeps (stages.clutter)."""

from __future__ import annotations

import numpy as np
import pytest

from fmcw_cl.stages import clutter, resample

WAVELENGTH_M = 1.55e-6
PERIOD_S = 50e-6


def _direct(x: np.ndarray, half: int) -> np.ndarray:
    """The definition: each row less the mean of the rows within `half` of it."""
    out = np.empty_like(x, dtype=np.float64)
    for i in range(x.shape[0]):
        out[i] = x[i] - x[max(0, i - half): i + half + 1].astype(np.float64).mean(axis=0)
    return out


@pytest.mark.parametrize("rows,half", [(0, 3), (1, 3), (4, 3), (7, 3), (300, 50), (101, 50)])
def test_running_mean_is_its_definition(rows, half):
    """At both ends (fewer rows in the mean), a window wider than the rows, one row."""
    rng = np.random.default_rng(rows)
    x = (rng.normal(0, 100, (rows, 64)) + 3000).astype(np.float32)
    got = clutter.without_still(x, half)
    assert got.dtype == np.float32 and got.shape == x.shape
    np.testing.assert_allclose(got, _direct(x, half), atol=2e-3)
    if rows == 1:
        assert not got.any()


@pytest.mark.parametrize("speed_mps", [2e-3, 0.05, 3.0])
def test_a_wall_goes_and_a_mover_stays(speed_mps):
    """Rows of a still tone (a wall, 10x the mover) and of a tone whose phase turns
    with the motion (4 pi v T / lambda a period) and whose frequency follows its
    distance: the wall falls by more than 60 dB, the mover keeps its power within 1 dB
    from 2 mm/s (its mean over 5 ms: 13 turns)."""
    points, pairs = 1000, 600
    win = resample.window(points)
    j = np.arange(points)
    t = np.arange(pairs) * PERIOD_S
    d = 0.2 + speed_mps * t
    cycles = d / 0.47 * points / 2                      # the tone's cycles over the half-sweep
    phase = 4 * np.pi * d / WAVELENGTH_M
    mover = np.cos(2 * np.pi * cycles[:, None] * j[None, :] / points + phase[:, None])
    wall = 10 * np.cos(2 * np.pi * 0.05 / 0.47 * points / 2 * j / points + 0.3)
    x = ((mover + wall[None, :]) * win).astype(np.float32)
    half = clutter.half_width(PERIOD_S)
    assert half == 50
    got = clutter.without_still(x, half)
    spec = np.abs(np.fft.rfft(got[half:-half], 2048, axis=1)) ** 2
    alone = np.abs(np.fft.rfft((wall * win)[None, :], 2048, axis=1)) ** 2
    moving = np.abs(np.fft.rfft((mover * win)[half:-half], 2048, axis=1)) ** 2
    at_wall = int(np.argmax(alone[0]))
    wall_left = 10 * np.log10(spec[:, at_wall].mean() / alone[0, at_wall])
    mine = np.argmax(moving, axis=1)
    kept = 10 * np.log10(spec[np.arange(mine.size), mine] / moving[np.arange(mine.size), mine])
    assert wall_left < -60 or (speed_mps < 0.01 and wall_left < -40), wall_left
    assert np.all(np.abs(kept) < 1.0), kept.min()


def test_half_width_follows_the_period():
    assert clutter.half_width(50e-6) == 50 and clutter.half_width(1e-3) == 2 and clutter.half_width(1.0) == 1


def _kept_db(speed_mps: float, span_s: float, tremble_m: float) -> tuple[float, float]:
    """On rows less their running mean over `span_s`: what is left of a wall (10x the
    mover) trembling `tremble_m` at 50 Hz (mean power, dB), and the least the mover keeps
    of its own (dB)."""
    points, pairs = 1000, 800
    win = resample.window(points)
    j = np.arange(points)
    t = np.arange(pairs) * PERIOD_S
    d = 0.2 + speed_mps * t
    mover = np.cos(2 * np.pi * (d / 0.47 * points / 2)[:, None] * j[None, :] / points
                   + (4 * np.pi * d / WAVELENGTH_M)[:, None])
    wall_phase = 4 * np.pi * tremble_m * np.sin(2 * np.pi * 50.0 * t) / WAVELENGTH_M
    wall = 10 * np.cos(2 * np.pi * 0.05 / 0.47 * points / 2 * j[None, :] / points + 0.3 + wall_phase[:, None])
    half = clutter.half_width(PERIOD_S, span_s)
    got = clutter.without_still(((mover + wall) * win).astype(np.float32), half)[half:-half]
    spec = np.abs(np.fft.rfft(got, 2048, axis=1)) ** 2
    alone = np.abs(np.fft.rfft((wall * win)[half:-half], 2048, axis=1)) ** 2
    moving = np.abs(np.fft.rfft((mover * win)[half:-half], 2048, axis=1)) ** 2
    at_wall = int(np.argmax(alone[0]))
    mine = np.argmax(moving, axis=1)
    rows = np.arange(mine.size)
    wall_left = 10 * np.log10(spec[:, at_wall].mean() / alone[:, at_wall].mean())
    return float(wall_left), float(np.min(-np.abs(10 * np.log10(spec[rows, mine] / moving[rows, mine]))))


def test_a_trembling_wall_goes_on_shorter_rows():
    """A wall trembling 1 um at 50 Hz turns its phase through +-8 rad: rows less their
    mean over 5 ms keep most of it, rows less their mean over 0.5 ms (TREMBLING_S) take
    it down by more than 15 dB; a mover keeps its power within 1 dB there from 3 mm/s."""
    left_long, _ = _kept_db(3.0, clutter.STILL_S, 1e-6)
    left_short, kept = _kept_db(3.0, clutter.TREMBLING_S, 1e-6)
    assert left_long > -6, left_long
    assert left_short < -15, left_short
    assert kept > -1.0, kept
    assert _kept_db(3e-3, clutter.TREMBLING_S, 1e-6)[1] > -1.0
