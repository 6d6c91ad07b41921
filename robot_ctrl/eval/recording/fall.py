"""FallCriterion: when a humanoid counts as fallen."""

from __future__ import annotations

from dataclasses import dataclass

from robot_ctrl.hw.types import JointState


@dataclass(frozen=True)
class FallCriterion:
    """Fallen when the base is below ``height_ratio`` of its nominal height above the floor
    (world z), or when any body but the feet touches the floor."""

    nominal_base_height: float  # [m]
    height_ratio: float = 0.6

    def reason(self, state: JointState) -> str | None:
        """Why the robot has fallen at this sample, or None."""
        if state.base_pos is not None and state.base_pos[2] < self.height_ratio * self.nominal_base_height:
            return f"base height {state.base_pos[2]:.3f} m < {self.height_ratio:.0%} of {self.nominal_base_height:.3f} m"
        if state.floor_contacts:
            return f"touching the floor: {', '.join(state.floor_contacts)}"
        return None
