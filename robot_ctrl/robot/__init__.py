"""Robot layer: configs, description files, Pinocchio model and the MuJoCo conversion.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "config": ["ConfigError", "RobotConfig"],
    "config_file": ["available_robots", "load_robot_config"],
    "model": ["RobotModel", "load_robot"],
})
