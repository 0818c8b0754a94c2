"""fmcw-cl: batch processor for FMCW LiDAR captures.

The data flow is one way: capture -> chunks -> stages -> pairs -> track.
"""

__version__ = "0.1.0"
