"""Robot description files from the ``example-robot-data`` package: locating them and reading the SRDF.

The URDF/SRDF/meshes are never copied into this repository (licence): they are read in place
from the installed package and converted at run time (see :mod:`robot_ctrl.robot.mjcf`).
"""

from __future__ import annotations

import importlib.metadata
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from robot_ctrl.robot.config import ConfigError, RobotConfig


@lru_cache(maxsize=1)
def robots_dir() -> Path:
    """Absolute path of example-robot-data's ``robots/`` folder."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError as exc:
        raise ConfigError("the 'example-robot-data' package is not installed (pip install example-robot-data)") from exc
    marker = "share/example-robot-data/robots/"
    for f in dist.files or ():
        text = str(f)
        if marker in text:
            return Path(dist.locate_file(text[: text.index(marker) + len(marker)])).resolve()
    raise ConfigError("example-robot-data is installed but its robots/ folder was not found")


def example_robot_data_version() -> str:
    return importlib.metadata.version("example-robot-data")


@dataclass(frozen=True)
class RobotFiles:
    urdf: Path
    srdf: Path | None


def robot_files(config: RobotConfig) -> RobotFiles:
    """Resolve the config's URDF and SRDF; a missing file lists what the package folder holds."""
    pkg = robots_dir() / config.package_dir
    if not pkg.is_dir():
        have = sorted(p.name for p in robots_dir().iterdir() if p.is_dir())
        raise ConfigError(f"description.package_dir {config.package_dir!r} not in example-robot-data; available: {have}")
    files = []
    for field, rel in (("urdf", config.urdf), ("srdf", config.srdf)):
        if rel is None:
            files.append(None)
            continue
        path = pkg / rel
        if not path.is_file():
            have = sorted(str(p.relative_to(pkg)) for p in pkg.glob(f"{Path(rel).parent}/*"))
            raise ConfigError(f"description.{field} {rel!r} not found in {pkg}; available: {have}")
        files.append(path)
    return RobotFiles(*files)


def resolve_package_uris(urdf_text: str) -> str:
    """Rewrite ``package://example-robot-data/robots/...`` mesh URIs to absolute paths.

    One Talos file writes ``package:///`` with three slashes; both forms are handled.
    """
    root = str(robots_dir()) + "/"
    for prefix in ("package:///example-robot-data/robots/", "package://example-robot-data/robots/"):
        urdf_text = urdf_text.replace(prefix, root)
    return urdf_text


@dataclass(frozen=True)
class SrdfInfo:
    """What the SRDF contributes: link pairs never checked for self-collision, and rotor parameters."""

    disabled_collisions: tuple[tuple[str, str], ...]
    rotor_armature: dict[str, float]  # joint -> rotor inertia * gear_ratio² [kg·m²]


def read_srdf(path: Path | None) -> SrdfInfo:
    if path is None:
        return SrdfInfo((), {})
    root = ET.parse(path).getroot()
    pairs = tuple((e.get("link1"), e.get("link2")) for e in root.iter("disable_collisions"))
    armature = {}
    for rotor in root.iter("rotor_params"):
        for j in rotor.iter("joint"):
            armature[j.get("name")] = float(j.get("mass", 0.0)) * float(j.get("gear_ratio", 1.0)) ** 2
    return SrdfInfo(pairs, armature)
