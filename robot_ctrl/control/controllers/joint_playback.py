"""JointPlayback: joint angles played on the servos as they are, after a walking controller's walk-in.

The naive baseline of thesis 3.8.4 ("Comparison with simple machine learning approach") learns
every joint's trajectory and sends the synthesized angles to the robot: no pattern generator, no
dynamic filter, no stabilizer, no IK. Until :meth:`play` is first called this controller is the
walking controller it wraps (the walk from standing into steady gait, as the thesis's sequences
start after a normal step); from then on each tick commands ``q`` = the angles last given, ``dq``
their finite difference, the robot's servo gains, and the same quasi-static gravity feedforward our
method's servos get (``static_feedforward``), for the played angles at the measured base, split
between the feet as their force sensors measure it: the servos hold the robot's weight as they do
for our method, so the comparison is of what is planned, not of how stiff the servos are.
"""

from __future__ import annotations

import numpy as np

from robot_ctrl.control.controllers.static_feedforward import static_torques
from robot_ctrl.control.controllers.walking_controller import WalkingController
from robot_ctrl.geometry import SIDES
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.robot.model import configuration

CONTACT_FORCE = 20.0  # [N] a foot's vertical force above it: the foot carries a share of the weight


class JointPlayback:
    def __init__(self, walking: WalkingController):
        self.walking = walking
        self.robot = walking.robot
        self.target: np.ndarray | None = None  # joint order [rad]; None: still walking in
        self._previous: np.ndarray | None = None
        self.last_command: JointCommand | None = None
        self.last_state: JointState | None = None
        self._statics = self.robot.pin.createData()

    @property
    def playing(self) -> bool:
        return self.target is not None

    def play(self, q: np.ndarray) -> None:
        """The joint angles [rad] (joint order) of the next tick."""
        if not np.all(np.isfinite(q)):
            raise FloatingPointError("playback angles are not finite; refusing to send them")
        self.target = np.asarray(q, dtype=float)

    def prepare(self) -> None:
        if not self.playing:
            self.walking.prepare()

    def step(self, state: JointState) -> JointCommand:
        self.last_state = state
        if not self.playing:
            self.last_command = self.walking.step(state)
            return self.last_command
        r = self.robot
        previous = self.last_command.q if self._previous is None else self._previous
        dq = (self.target - previous) / self.walking.dt
        self._previous = self.target.copy()
        self.last_command = JointCommand(q=self.target.copy(), dq=dq, kp=r.kp, kd=r.kd,
                                         tau_ff=self._gravity(state)[r.v_index])
        return self.last_command

    def _gravity(self, state: JointState) -> np.ndarray:
        """Quasi-static torques (nv,) of the played angles at the measured base, the weight split
        between the feet by their measured vertical forces (none: no feedforward)."""
        forces = {s: float((state.foot_wrench or {}).get(s, np.zeros(6))[2]) for s in SIDES}
        down = [s for s in SIDES if forces[s] > CONTACT_FORCE]
        if not down or state.base_pos is None:
            return np.zeros(self.robot.pin.nv)
        q = configuration(self.robot, state.base_pos, state.base_quat_xyzw, self.target)
        frames = [self.robot.frame_ids[f"{s}_foot"] for s in down]
        tau, _ = static_torques(self.robot.pin, self._statics, q, frames, [forces[s] for s in down])
        return tau

    def close(self) -> None:
        self.walking.close()
