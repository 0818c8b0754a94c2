"""A physical simulator of the FMCW LiDAR: DFB laser, moving target, two-channel ADC."""

from .laser import DfbLaser, paper_dfb
from .many import simulate_captures
from .scene import DURATIONS_S, SCENARIOS, Trajectory, jump, rail, static
from .writer import LAB, SimulationConfig, simulate_capture

__all__ = ["DfbLaser", "paper_dfb", "Trajectory", "static", "rail", "jump", "SCENARIOS", "DURATIONS_S",
           "SimulationConfig", "LAB", "simulate_capture", "simulate_captures"]
