"""Evaluation: fall detection and run metrics computed from what the hardware adapter reads."""

from robot_ctrl.eval.fall import FallCriterion
from robot_ctrl.eval.run_metrics import RunMetrics

__all__ = ["FallCriterion", "RunMetrics"]
