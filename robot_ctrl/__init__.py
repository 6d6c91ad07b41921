"""robot_ctrl: a control stack for humanoid robots (MPC walking, stack-of-tasks IK, hardware adapters)."""

import os
from pathlib import Path

from threadpoolctl import threadpool_limits

__version__ = "0.1.0"

# One BLAS thread. Every matrix of the control loop is small (the IK's 38 columns, the MPC's 36
# variables): a second thread gains nothing, and OpenBLAS's waiting threads spin on the cores that
# the simulated robot's process and the dynamic filter's worker need (README, setup: 3.3x instead of
# 5.8x real time). Libraries loaded later read the variable; those already loaded are limited here.
# Set OPENBLAS_NUM_THREADS before importing robot_ctrl to choose another count.
threadpool_limits(int(os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")), user_api="blas")

#: Repository root: configs/, sim/ and models/ live beside the package (editable install).
ROOT = Path(__file__).resolve().parent.parent
