"""A physical simulator of the FMCW LiDAR: DFB laser, moving target, two-channel ADC."""

from .laser import DfbLaser, paper_dfb
from .many import simulate_captures
from .scene import DURATIONS_S, SCENARIOS, Trajectory, creep, glide, jump, rail, static, sway, vibration
from .writer import LAB, Mover, SimulationConfig, simulate_capture

__all__ = ["DfbLaser", "paper_dfb", "Trajectory", "static", "rail", "jump", "glide", "sway", "vibration",
           "creep", "Mover",
           "SCENARIOS", "DURATIONS_S", "SimulationConfig", "LAB", "simulate_capture", "simulate_captures"]
