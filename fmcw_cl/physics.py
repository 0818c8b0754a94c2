"""Physical constants and the FMCW relations used throughout (SI units)."""

from __future__ import annotations

C = 299_792_458.0  # speed of light in vacuum, m/s


def range_resolution(bandwidth_hz: float, n: float = 1.0) -> float:
    """Range resolution c / (2 n B) in metres (one FFT bin of the resampled sweep)."""
    return C / (2.0 * n * abs(bandwidth_hz))


def unambiguous_range(points: int, bandwidth_hz: float, n: float = 1.0) -> float:
    """Largest distance N c / (4 n B) in metres that N resampled points can hold."""
    return points * C / (4.0 * n * abs(bandwidth_hz))


def delay_of(distance_m, n: float = 1.0):
    """Round-trip delay tau = 2 R n / c in seconds for a one-way distance R."""
    return 2.0 * distance_m * n / C


def doppler_shift(velocity_mps, wavelength_m: float, n: float = 1.0):
    """Doppler beat shift 2 n v / lambda in Hz (positive when the distance grows)."""
    return 2.0 * n * velocity_mps / wavelength_m
