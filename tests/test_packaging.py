"""The package as a user installs it: a wheel that carries its configs and models and runs from any folder."""

import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_the_wheel_carries_every_subpackage_the_configs_and_the_models(tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                    str(tmp_path), str(ROOT)], check=True, capture_output=True)
    wheel = next(tmp_path.glob("robot_ctrl-*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    for folder in sorted(p.parent for p in (ROOT / "robot_ctrl").rglob("*.py")):
        module = folder.relative_to(ROOT).as_posix()
        assert any(n.startswith(module + "/") for n in names), f"{module} is missing from the wheel (pyproject packages)"
    for data in ("configs/robots/talos.yaml", "configs/hw/talos_mit_can.yaml", "configs/trials/hard_rooms.txt",
                 "models/talos_walk_reach_demos.npz",
                 "models/talos_gait_profile.json", "sim/floor.xml"):
        assert f"robot_ctrl/_data/{data}" in names
    # Installed from the wheel (dependencies from this environment), run from another folder.
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target), str(wheel)],
                   check=True, capture_output=True)
    probe = ("import robot_ctrl; from robot_ctrl.robot.config_file import load_robot_config; "
             "from robot_ctrl.synthesis.demonstrations import DemonstrationSet, default_dataset_path; "
             "print(robot_ctrl.__file__); print(load_robot_config('talos').name); "
             "print(len(DemonstrationSet.load(default_dataset_path('talos')).trials))")
    out = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, env={"PYTHONPATH": str(target), "PATH": "/usr/bin"},
                         check=True, capture_output=True, text=True).stdout.split()
    assert out[0].startswith(str(target)) and out[1] == "talos" and int(out[2]) > 0
