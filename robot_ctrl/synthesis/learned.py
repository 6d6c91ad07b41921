"""The learned walk-and-reach primitives of a robot: its demonstration set loaded, the primitives
learned from it once and cached.

The cache (``$ROBOT_CTRL_CACHE``, beside the converted robot scenes) is keyed by the demonstration
file's bytes, the robot's name and joint limits (the primitives' clip range), the source of
``robot_ctrl/synthesis/`` (the learning code and its settings) and numpy's version, so any change to
what the learning reads or does learns anew.
"""

from __future__ import annotations

import hashlib
import os
import pickle
from pathlib import Path

import numpy as np

from robot_ctrl.robot.mjcf import cache_dir
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.synthesis.demonstrations import DemonstrationSet, default_dataset_path
from robot_ctrl.synthesis.primitives import WalkReachPrimitives

SYNTHESIS_SOURCES = Path(__file__).resolve().parent  # the learning code, part of the key


def load_demonstrations(robot: RobotModel, dataset: Path | None = None, whole_body: bool = False) -> DemonstrationSet:
    """The robot's demonstration set (default: the one shipped in ``models/`` for the method)."""
    path = dataset or default_dataset_path(robot.name, whole_body)
    if not path.exists():
        physics = " --from-physics" if whole_body else ""  # only a set recorded in physics holds the legs
        raise FileNotFoundError(f"no demonstrations at {path}; generate them with: robot-ctrl synth-demos "
                                f"--robot {robot.name}{physics} --out {path}")
    return DemonstrationSet.load(path)


#: Periodic sources of the mixture model: (for action 1, more for actions 2 and 3). The thesis's
#: robot primitives use 4 + 3 (3.8.3); on our demonstration sets 3 + 2 reach Q >= 0.988 per action
#: (``robot-ctrl synth-quality --sources 3+2,4+3,5+4``).
DEFAULT_SOURCES = (3, 2)


def load_primitives(robot: RobotModel, dataset: Path | None = None, sources: tuple[int, int] = DEFAULT_SOURCES, *,
                    whole_body: bool = False) -> WalkReachPrimitives:
    """The primitives learned from the robot's demonstration set with ``sources`` periodic sources:
    from the cache when the same demonstrations were learned by the same code before, else learned
    (a few seconds) and cached. ``whole_body``: learn every joint and the base (the naive baseline)
    instead of the pelvis twist and the upper body."""
    demos = load_demonstrations(robot, dataset, whole_body)
    if whole_body:
        demos = demos.whole_body()
    path = dataset or default_dataset_path(robot.name, whole_body)
    key = hashlib.sha256()
    key.update(Path(path).read_bytes())
    key.update(robot.name.encode() + robot.lower.tobytes() + robot.upper.tobytes() + np.__version__.encode())
    key.update(repr((tuple(sources), whole_body)).encode())
    for source in sorted(SYNTHESIS_SOURCES.glob("*.py")):
        key.update(source.read_bytes())
    kind = "whole-body-primitives" if whole_body else "primitives"
    cached = cache_dir() / f"{robot.name}-{kind}-{key.hexdigest()[:16]}.pickle"
    if cached.is_file():
        with open(cached, "rb") as f:
            return pickle.load(f)
    primitives = WalkReachPrimitives.learn(demos, robot, *sources)
    cached.parent.mkdir(parents=True, exist_ok=True)
    partial = cached.with_suffix(f".{os.getpid()}.partial")
    with open(partial, "wb") as f:
        pickle.dump(primitives, f)
    os.replace(partial, cached)  # whole or absent, whichever process of a campaign writes it first
    return primitives
