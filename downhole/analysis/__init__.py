"""Analysis: drilling metrics (stick-slip severity, bit bounce, ROP, MSE) and plots."""

from downhole.analysis.metrics import SUMMARY_KEYS, stick_slip_severity, summarize

__all__ = ["SUMMARY_KEYS", "stick_slip_severity", "summarize"]
