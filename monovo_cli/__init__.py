"""monovo: intensity-difference based monocular visual odometry (Martinez, ch. 10)."""

__version__ = "0.1.0"
