"""Robot layer: configs, description files, Pinocchio model and the MuJoCo conversion."""

from robot_ctrl.robot.config import ConfigError, RobotConfig, available_robots, load_robot_config
from robot_ctrl.robot.model import RobotModel, load_robot

__all__ = ["ConfigError", "RobotConfig", "RobotModel", "available_robots", "load_robot", "load_robot_config"]
