import pytest

from robot_ctrl.robot import load_robot


@pytest.fixture(scope="session")
def talos():
    return load_robot("talos")
