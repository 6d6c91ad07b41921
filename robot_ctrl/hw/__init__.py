"""The hardware interface and the safety layer. **Every line here is safety-critical**: it is
the last code between a controller and real servos.

- ``adapter``: ``HardwareAdapter``, the lifecycle (after ros2_control) and ``read``/``write`` every
  backend implements; ``HardwareFault``.
- ``types``: what crosses the interface, ``JointState`` (measured) and ``JointCommand``.
- ``safety``: ``SafetyLayer``, which wraps any backend so that only safe commands reach it;
  ``safety_limits`` (what it holds commands within), ``command_filter`` (its per-tick pass, compiled),
  ``servo_torque`` (the torque a command produces, bounded to the servo's effort);
  ``held_signals`` (Ctrl-C and SIGTERM held while the servos are brought to their safe state).

The backends live elsewhere: the simulated robot in ``robot_ctrl.sim``, real servo buses in
``robot_ctrl.buses``.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "adapter": ["HardwareAdapter", "HardwareFault", "LifecycleError"],
    "types": ["CommandError", "JointCommand", "JointState", "LifecycleState"],
    "safety": ["SafetyLayer", "SafetyMode"],
    "safety_limits": ["SafetyLimits"],
    "servo_torque": ["bound_servo_torque"],
})
