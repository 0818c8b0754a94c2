"""The DFB laser: nonlinear current tuning G(I), output power, phase noise.

The tuning follows the paper's Fig. 3: 1548.12 nm at 20 mA to 1549.76 nm at 500 mA
(205 GHz), 160 GHz between 160 and 480 mA. The optical frequency falls as the current
rises, faster at high current (Joule heating), modelled as a quadratic in the current.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics import C


@dataclass(frozen=True)
class DfbLaser:
    """nu(I) = nu_ref - a (I - i_ref) - b (I - i_ref)^2, power ~ (I - threshold).

    Attributes
    ----------
    nu_ref_hz : optical frequency at `i_ref_a` (Hz).
    i_ref_a : reference current (A).
    a_hz_per_a, b_hz_per_a2 : linear and quadratic tuning coefficients (>0: red shift).
    threshold_a : lasing threshold (A); output power is proportional to I - threshold.
    linewidth_hz : Lorentzian linewidth (Hz) of the free-running laser.
    """

    nu_ref_hz: float
    i_ref_a: float
    a_hz_per_a: float
    b_hz_per_a2: float
    threshold_a: float = 0.012
    linewidth_hz: float = 1.0e6

    def frequency(self, current_a):
        """Optical frequency (Hz) at injection current(s) `current_a` (A)."""
        x = np.asarray(current_a, dtype=np.float64) - self.i_ref_a
        return self.nu_ref_hz - (self.a_hz_per_a + self.b_hz_per_a2 * x) * x

    def frequency_offset(self, current_a):
        """frequency(I) - nu_ref (Hz): the small part, kept apart for precision."""
        x = np.asarray(current_a, dtype=np.float64) - self.i_ref_a
        return -(self.a_hz_per_a + self.b_hz_per_a2 * x) * x

    def tuning_slope(self, current_a):
        """d nu / d I (Hz/A), negative for a DFB."""
        x = np.asarray(current_a, dtype=np.float64) - self.i_ref_a
        return -(self.a_hz_per_a + 2.0 * self.b_hz_per_a2 * x)

    def relative_power(self, current_a):
        """Output power relative to its value at 320 mA (dimensionless)."""
        i = np.asarray(current_a, dtype=np.float64)
        return np.maximum(i - self.threshold_a, 0.0) / (0.320 - self.threshold_a)

    def tuning_table(self, rng: np.random.Generator, points: int = 25, lo_a: float = 0.020,
                     hi_a: float = 0.500, noise_hz: float = 5e6) -> tuple[np.ndarray, np.ndarray]:
        """An offline G(I) measurement: `points` currents and noisy absolute frequencies.

        `noise_hz` is the rms error of the wavelength meter (5 MHz = 0.04 pm at 1549 nm).
        The table's noise sets the absolute distance scale: 20 MHz rms gave up to
        0.16 mm of bias at 0.8 m, 5 MHz about a quarter of that.
        """
        cur = np.linspace(lo_a, hi_a, points)
        return cur, self.frequency(cur) + rng.normal(0.0, noise_hz, points)


def paper_dfb(linewidth_hz: float = 1.0e6) -> DfbLaser:
    """The paper's DFB: 205 GHz over 20-500 mA and 160 GHz over 160-480 mA."""
    i_ref = 0.020
    nu_ref = C / 1548.12e-9
    # Solve a*x + b*x^2 for the two spans (x measured from 20 mA).
    x1, x2, x3 = 0.160 - i_ref, 0.480 - i_ref, 0.500 - i_ref
    m = np.array([[x3, x3**2], [x2 - x1, x2**2 - x1**2]])
    a, b = np.linalg.solve(m, [205e9, 160e9])
    return DfbLaser(nu_ref, i_ref, float(a), float(b), linewidth_hz=linewidth_hz)
