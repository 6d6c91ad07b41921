"""robot_ctrl: a control stack for humanoid robots (MPC walking, stack-of-tasks IK, hardware adapters).

What a user composes, in one flat namespace::

    robot = load_robot("talos")
    with open_hardware("mujoco", robot) as hw:
        hw.bring_up()
        state = hw.read()
        controller = WalkingController(robot, state, WalkingOptions())
        ...

See ``examples/`` for whole scripts. The names are imported on first use, so that
``import robot_ctrl`` (and the command line) stays quick.
"""

import importlib
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

#: Public name → the module that defines it.
_EXPORTS = {
    # robots
    "RobotModel": "robot_ctrl.robot.model", "load_robot": "robot_ctrl.robot.model",
    "configuration": "robot_ctrl.robot.model", "RobotConfig": "robot_ctrl.robot.config",
    "ConfigError": "robot_ctrl.robot.config",
    # hardware: adapters, what crosses them, disturbances of a simulated robot
    "open_hardware": "robot_ctrl.hw.hardware", "HardwareAdapter": "robot_ctrl.hw.adapter",
    "HardwareFault": "robot_ctrl.hw.adapter", "SafetyLayer": "robot_ctrl.hw.safety", "SafetyMode": "robot_ctrl.hw.safety",
    "JointState": "robot_ctrl.hw.types", "JointCommand": "robot_ctrl.hw.types", "LifecycleState": "robot_ctrl.hw.types",
    "Disturbances": "robot_ctrl.hw.disturbances", "Push": "robot_ctrl.hw.disturbances",
    "DrawerPlacement": "robot_ctrl.hw.drawer_cabinet",
    # modes a user chooses between
    "ArmMotion": "robot_ctrl.modes", "BaseState": "robot_ctrl.modes", "FilterMode": "robot_ctrl.modes",
    "HardwareKind": "robot_ctrl.modes",
    # the pipeline's stages and the values between them
    "WalkParams": "robot_ctrl.wpg.params", "Footstep": "robot_ctrl.wpg.footstep", "GaitPhase": "robot_ctrl.wpg.plan",
    "WalkReference": "robot_ctrl.wpg.plan", "PlanPreview": "robot_ctrl.wpg.plan", "Touchdown": "robot_ctrl.wpg.plan",
    "WholeBodyIK": "robot_ctrl.sot.whole_body_ik", "Action": "robot_ctrl.synthesis.step_planning",
    # controllers, their commands and commanders, the loop
    "WalkingController": "robot_ctrl.control.walking_controller",
    "WalkingOptions": "robot_ctrl.control.walking_controller", "PlanSample": "robot_ctrl.control.walking_controller",
    "BalanceController": "robot_ctrl.control.balance_controller",
    "BalanceParams": "robot_ctrl.control.balance_controller", "static_torques": "robot_ctrl.control.static_feedforward",
    "PathCommander": "robot_ctrl.control.path_commander", "WalkGoal": "robot_ctrl.control.path_follower",
    "ControlLoop": "robot_ctrl.control.loop", "LoopResult": "robot_ctrl.control.loop", "Tick": "robot_ctrl.control.loop",
    # recorders, stop conditions, metrics and reports
    "RunMetrics": "robot_ctrl.eval.run_metrics", "FallCriterion": "robot_ctrl.eval.fall",
    "MetricsRecorder": "robot_ctrl.eval.recorders", "ProgressBar": "robot_ctrl.eval.recorders",
    "Fell": "robot_ctrl.eval.recorders", "TimeLimit": "robot_ctrl.eval.recorders", "HeldFor": "robot_ctrl.eval.recorders",
    "write_report": "robot_ctrl.eval.report_file", "render_report": "robot_ctrl.eval.html_report",
    # scenarios: one user task each
    "run_walk": "robot_ctrl.scenarios.walk", "WalkSettings": "robot_ctrl.scenarios.walk",
    "run_balance": "robot_ctrl.scenarios.balance", "run_drawer": "robot_ctrl.scenarios.drawer",
    "DrawerTask": "robot_ctrl.scenarios.drawer_task", "load_primitives": "robot_ctrl.synthesis.learned",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'robot_ctrl' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
