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

import os
import sys
from pathlib import Path

from threadpoolctl import threadpool_limits

from robot_ctrl.lazy_exports import lazy_exports

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

#: Each public name under the module that defines it (relative to robot_ctrl).
__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    # robots
    "robot.model": ["RobotModel", "load_robot", "configuration"], "robot.config": ["RobotConfig", "ConfigError"],
    # hardware: the interface, what crosses it, the safety layer; backends chosen by name
    "hw.adapter": ["HardwareAdapter", "HardwareFault"], "hw.safety": ["SafetyLayer", "SafetyMode"],
    "hw.types": ["JointState", "JointCommand", "LifecycleState"], "backends": ["open_hardware"],
    # the simulated world: disturbances of a simulated robot, props
    "sim.disturbances": ["Disturbances", "Push"], "sim.drawer_cabinet": ["DrawerPlacement"],
    # modes a user chooses between
    "modes": ["ArmMotion", "BaseState", "FilterMode", "HardwareKind"],
    # the pipeline's stages and the values between them
    "wpg.params": ["WalkParams"], "wpg.footstep": ["Footstep"],
    "wpg.plan": ["GaitPhase", "WalkReference", "PlanPreview", "Touchdown"],
    "sot.whole_body_ik": ["WholeBodyIK"], "synthesis.step_planning": ["Action"],
    "synthesis.learned": ["load_primitives"],
    # controllers, their commands and commanders, the loop
    "control.controllers.walking_controller": ["WalkingController", "WalkingOptions", "PlanSample"],
    "control.controllers.balance_controller": ["BalanceController", "BalanceParams"],
    "control.controllers.static_feedforward": ["static_torques"],
    "control.commanders.path_commander": ["PathCommander"], "control.commanders.path_follower": ["WalkGoal"],
    "control.loop.control_loop": ["ControlLoop", "LoopResult", "Tick"],
    # recorders, stop conditions, metrics and reports
    "eval.recording.run_metrics": ["RunMetrics"], "eval.recording.fall": ["FallCriterion"],
    "eval.recording.recorders": ["MetricsRecorder", "ProgressBar", "Fell", "TimeLimit", "HeldFor"],
    "eval.recording.report_file": ["write_report"], "eval.reports.html_report": ["render_report"],
    # scenarios: one user task each
    "scenarios.walk": ["run_walk", "WalkSettings"], "scenarios.balance": ["run_balance"],
    "scenarios.drawer": ["run_drawer"], "scenarios.drawer_task": ["DrawerTask"],
})
