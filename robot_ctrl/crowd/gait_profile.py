"""GaitProfile: the gait's propagation speed over one gait cycle, g(φ) = dz/dφ (thesis 4.4.1).

The crowd laws advance an agent by ``ż = (1 + μ) ω g(φ)``; the certificates need min, max and mean
of g. For a walking robot g is measured (``robot-ctrl crowd gait-profile``): the forward speed of
the measured CoM, binned over the gait phase of the pattern generator (2π per two steps), divided
by the gait frequency. Stored as ``models/<robot>_gait_profile.json``; without that file a constant
profile (speed / ω) stands in and the report says so. Speeds scale linearly with the walking
speed (step length), the approximation the thesis measured for step-length morphing (Fig. 4.9a).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_ctrl import ROOT

MODELS = ROOT / "models"


def binned_speed(phases: np.ndarray, speeds: np.ndarray, bins: int = 32) -> np.ndarray:
    """Mean of ``speeds`` [m/s] in ``bins`` equal bins of the gait phase (mod 2π) [rad]."""
    phases, speeds = np.asarray(phases, dtype=float), np.asarray(speeds, dtype=float)
    index = np.floor((phases % (2 * np.pi)) / (2 * np.pi) * bins).astype(int) % bins
    count = np.bincount(index, minlength=bins)
    if np.any(count == 0):
        raise ValueError(f"every phase bin needs samples; empty bins: {np.flatnonzero(count == 0).tolist()}")
    return np.bincount(index, weights=speeds, minlength=bins) / count


@dataclass(frozen=True)
class GaitProfile:
    speed: np.ndarray  # forward speed [m/s] per phase bin at the nominal speed and frequency
    nominal_speed: float  # [m/s]
    omega: float  # gait frequency the profile was measured at [rad/s]
    source: str

    @property
    def g(self) -> np.ndarray:
        """g(φ) = dz/dφ [m/rad] per phase bin."""
        return self.speed / self.omega

    def scaled(self, speed: float, omega: float) -> "GaitProfile":
        """The profile at another mean speed and gait frequency (speeds scale with step length)."""
        return GaitProfile(self.speed * speed / self.nominal_speed, speed, omega, self.source)

    def to_json(self) -> dict:
        return {"speed_mps": self.speed.round(5).tolist(), "nominal_speed_mps": self.nominal_speed,
                "omega_rad_s": self.omega, "source": self.source}

    @classmethod
    def from_json(cls, data: dict) -> "GaitProfile":
        speed = np.asarray(data["speed_mps"], dtype=float)
        if speed.ndim != 1 or len(speed) < 4 or np.any(~np.isfinite(speed)) or np.any(speed <= 0):
            raise ValueError("gait profile speed_mps must be ≥ 4 finite speeds > 0")
        return cls(speed, float(data["nominal_speed_mps"]), float(data["omega_rad_s"]), str(data["source"]))

    @classmethod
    def load_or_constant(cls, robot: str, omega: float, speed: float, models: Path = MODELS) -> "GaitProfile":
        path = models / f"{robot}_gait_profile.json"
        if path.is_file():
            profile = cls.from_json(json.loads(path.read_text()))
            return cls(profile.scaled(speed, omega).speed, speed, omega, f"measured ({path.name})")
        return cls(np.full(32, float(speed)), speed, omega, "constant (no measured profile)")
