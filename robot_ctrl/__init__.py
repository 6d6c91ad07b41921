"""robot_ctrl: a control stack for humanoid robots (MPC walking, stack-of-tasks IK, hardware adapters)."""

from pathlib import Path

__version__ = "0.1.0"

#: Repository root: configs/, sim/ and models/ live beside the package (editable install).
ROOT = Path(__file__).resolve().parent.parent
