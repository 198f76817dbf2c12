"""downhole: down-hole drilling dynamics, optimization and control in Python."""

__version__ = "0.1.0"
