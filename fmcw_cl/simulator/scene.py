"""Target trajectories: static, guide rail, jumping robot leg.

A trajectory is tabulated on a fine time grid (distance, velocity, acceleration) and
evaluated anywhere by cubic Hermite interpolation, so that the simulator and the
accuracy checks share one exact truth.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.special import erf

GRID_S = 5e-6  # tabulation step; Hermite error is below 1e-15 m for these motions


@dataclass(frozen=True)
class Trajectory:
    """Distance R(t) (m), velocity (m/s), acceleration (m/s^2) on a uniform grid."""

    t0: float
    dt: float
    distance: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    @classmethod
    def from_velocity(cls, t0: float, t1: float, velocity: Callable, acceleration: Callable,
                      r0: float, dt: float = GRID_S) -> Trajectory:
        """Integrate an analytic velocity into distance (Euler-Maclaurin, 4th order)."""
        t = t0 + dt * np.arange(int(np.ceil((t1 - t0) / dt)) + 2)
        v, a = velocity(t), acceleration(t)
        steps = dt * (v[:-1] + v[1:]) / 2 + dt * dt * (a[:-1] - a[1:]) / 12
        r = r0 + np.concatenate([[0.0], np.cumsum(steps)])
        return cls(t0, dt, r, v, a)

    @property
    def t1(self) -> float:
        return self.t0 + self.dt * (self.distance.size - 1)

    def at(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(distance, velocity, acceleration) at times `t` (s), Hermite-interpolated."""
        i, s, h00, h10, h01, h11 = self._hermite(t)
        h, v, a = self.dt, self.velocity, self.acceleration
        # velocity: Hermite with the acceleration as derivative; acceleration: linear
        vel = h00 * v[i] + h10 * h * a[i] + h01 * v[i + 1] + h11 * h * a[i + 1]
        acc = (1 - s) * a[i] + s * a[i + 1]
        return self._distance(i, h00, h10, h01, h11), vel, acc

    def distance_at(self, t) -> np.ndarray:
        """The distance (m) of `at`, alone (the simulator's beat needs no more)."""
        i, _, *basis = self._hermite(t)
        return self._distance(i, *basis)

    def _hermite(self, t) -> tuple:
        """The grid index of each time, its fraction s and the cubic Hermite basis at s."""
        x = (np.asarray(t, dtype=np.float64) - self.t0) / self.dt
        i = np.clip(np.floor(x).astype(np.int64), 0, self.distance.size - 2)
        s = x - i
        s2, s3 = s * s, s * s * s
        return i, s, 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, 3 * s2 - 2 * s3, s3 - s2

    def _distance(self, i, h00, h10, h01, h11) -> np.ndarray:
        r, v, h = self.distance, self.velocity, self.dt
        return h00 * r[i] + h10 * h * v[i] + h01 * r[i + 1] + h11 * h * v[i + 1]


def static(duration: float, distance: float = 0.3) -> Trajectory:
    """A target at rest at `distance` metres."""
    zero = np.zeros_like
    return Trajectory.from_velocity(0.0, duration, zero, zero, distance, dt=1e-3)


def _smooth_ramp(x, w):
    """Integral of the smoothed unit step 0.5 (1 + erf(x/w))."""
    return 0.5 * (x * (1 + erf(x / w)) + w / np.sqrt(np.pi) * np.exp(-(x / w) ** 2))


def rail(duration: float, start_m: float = 0.06, peak_mps: float = 2.7, accel_mps2: float = 22.5,
         t_start: float = 0.05, edge_s: float = 0.012) -> Trajectory:
    """A guide-rail move: accelerate at `accel_mps2`, then brake, rest at both ends.

    The acceleration is a pair of opposite plateaus with smooth (erf) edges, so the
    velocity peaks at about `peak_mps` and the travel is peak^2 / accel (0.32 m).
    """
    ta = peak_mps / accel_mps2 + edge_s / np.sqrt(np.pi)  # the smooth edges cost some speed
    edges = (t_start, t_start + ta, t_start + 2 * ta)

    def acc(t):
        e = [0.5 * (1 + erf((t - te) / edge_s)) for te in edges]
        return accel_mps2 * (e[0] - 2 * e[1] + e[2])

    def vel(t):
        f = [_smooth_ramp(t - te, edge_s) for te in edges]
        return accel_mps2 * (f[0] - 2 * f[1] + f[2])

    return Trajectory.from_velocity(0.0, duration, vel, acc, start_m)


@dataclass(frozen=True)
class _Bump:
    """A velocity bump: half-Gaussians of widths left/right around a peak (m/s, s)."""

    peak: float
    at: float
    left: float
    right: float

    def sigma(self, t):
        return np.where(t < self.at, self.left, self.right)

    def velocity(self, t):
        s = self.sigma(t)
        return self.peak * np.exp(-0.5 * ((t - self.at) / s) ** 2)

    def acceleration(self, t):
        s = self.sigma(t)
        return -self.velocity(t) * (t - self.at) / (s * s)

    @property
    def travel(self) -> float:
        return self.peak * np.sqrt(np.pi / 2) * (self.left + self.right)


def jump(duration: float, ground_m: float = 0.07) -> Trajectory:
    """The paper's single-leg jump (Fig. 10), foot height over the ground.

    Leg protraction to 7.15 m/s at 78 ms (about +-360 m/s^2), a second protraction
    (2.84 m/s at 128 ms), an apex of about 0.3 m near 150 ms, a powered descent that
    lands at about 200 ms with about 300 m/s^2, a small bounce and a second strike of
    about 80 m/s^2 near 250 ms; at rest on the ground outside.
    """
    up1 = _Bump(7.15, 0.078, 0.012, 0.012)
    up2 = _Bump(2.84, 0.128, 0.0055, 0.0055)
    down_peak, down_right = -5.0, 0.607 * 5.0 / 300.0
    down_left = (up1.travel + up2.travel) / (abs(down_peak) * np.sqrt(np.pi / 2)) - down_right
    down = _Bump(down_peak, 0.187, down_left, down_right)
    hop = _Bump(0.45, 0.222, 0.007, 0.007)
    strike_right = 0.607 * 0.55 / 78.0
    strike = _Bump(-0.55, 0.243, hop.travel / (0.55 * np.sqrt(np.pi / 2)) - strike_right,
                   strike_right)
    bumps = (up1, up2, down, hop, strike)

    def vel(t):
        return sum(b.velocity(t) for b in bumps)

    def acc(t):
        return sum(b.acceleration(t) for b in bumps)

    return Trajectory.from_velocity(0.0, max(duration, 0.3), vel, acc, ground_m)


def glide(duration: float, start_m: float, end_m: float, t_start: float, t_end: float) -> Trajectory:
    """At rest at `start_m`, then a smooth move (a raised-cosine velocity) to `end_m`
    between `t_start` and `t_end` (s), at rest there after: a hand put into the beam, a
    target moved while something hides it, a slow pass through a wall's distance."""
    span = t_end - t_start

    def vel(t):
        x = np.clip((t - t_start) / span, 0.0, 1.0)
        inside = (t > t_start) & (t < t_end)
        return np.where(inside, (end_m - start_m) / span * (1 - np.cos(2 * np.pi * x)), 0.0)

    def acc(t):
        x = np.clip((t - t_start) / span, 0.0, 1.0)
        inside = (t > t_start) & (t < t_end)
        return np.where(inside, (end_m - start_m) / span**2 * 2 * np.pi * np.sin(2 * np.pi * x), 0.0)

    return Trajectory.from_velocity(0.0, duration, vel, acc, start_m)


def sway(duration: float, centre_m: float = 0.42, amplitude_m: float = 0.02, frequency_hz: float = 4.0,
         phase: float = 0.0) -> Trajectory:
    """A sinusoidal sway about `centre_m`: a cable, a second limb, a swinging object."""
    w = 2 * np.pi * frequency_hz

    def vel(t):
        return amplitude_m * w * np.cos(w * t + phase)

    def acc(t):
        return -amplitude_m * w * w * np.sin(w * t + phase)

    return Trajectory.from_velocity(0.0, duration, vel, acc, centre_m + amplitude_m * np.sin(phase))


def vibration(duration: float, distance: float = 0.3, amplitude_m: float = 50e-6,
              frequency_hz: float = 1000.0) -> Trajectory:
    """A target vibrating about `distance` (m): amplitude `amplitude_m` (m) at
    `frequency_hz` (50 um at 1 kHz: 0.31 m/s, 1970 m/s^2 at its peaks)."""
    return sway(duration, distance, amplitude_m, frequency_hz)


def creep(duration: float, distance: float = 0.3, speed_mps: float = 1e-3) -> Trajectory:
    """A target moving away from `distance` (m) at a constant `speed_mps` (m/s)."""
    def vel(t):
        return np.full_like(t, speed_mps)

    return Trajectory.from_velocity(0.0, duration, vel, np.zeros_like, distance, dt=1e-4)


SCENARIOS: dict[str, Callable[..., Trajectory]] = {"static": static, "rail": rail, "jump": jump,
                                                   "vibration": vibration, "creep": creep}
# default capture length of each
DURATIONS_S = {"static": 0.05, "rail": 0.4, "jump": 0.3, "vibration": 0.1, "creep": 0.2}
