"""robot_ctrl: a control stack for humanoid robots (MPC walking, stack-of-tasks IK, hardware adapters)."""

import os
import sys
from pathlib import Path

from threadpoolctl import threadpool_limits

__version__ = "0.1.0"

# One BLAS thread. Every matrix of the control loop is small (the IK's 38 columns, the MPC's 36
# variables): a second thread gains nothing, and OpenBLAS's waiting threads spin on the cores that
# the simulated robot's process and the dynamic filter's worker need (docs/architecture.md). Libraries
# loaded later read the variable; those already loaded are limited here.
# Set OPENBLAS_NUM_THREADS before importing robot_ctrl to choose another count.
threadpool_limits(int(os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")), user_api="blas")

# MuJoCo's offscreen renderer (--video) through EGL where there is no display; mujoco reads the
# variable when it is imported. Set MUJOCO_GL before importing robot_ctrl to choose otherwise.
if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
    os.environ.setdefault("MUJOCO_GL", "egl")

#: Where configs/, models/ and sim/ are: inside the installed package (robot_ctrl/_data), or beside
#: the package in a checkout (editable install).
_INSTALLED = Path(__file__).resolve().parent / "_data"
ROOT = _INSTALLED if (_INSTALLED / "configs").is_dir() else Path(__file__).resolve().parent.parent
