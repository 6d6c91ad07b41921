"""AttitudeFilter: the IMU's attitude fused with its gyro, before the state estimator.

The explicit complementary filter on SO(3) of Mahony, Hamel and Pflimlin (IEEE TAC 53(5), 2008,
eq. 13): the estimate turns with the gyro (no lag on the motion) and is pulled toward the attitude
reading by the gain ``a_n = max(1/n, dt/τ)`` at the n-th reading: the mean of the readings so far (a
Kalman filter's gain on a constant), down to a floor set by the time constant ``τ`` = 1 s (how fast
the gyro's own errors are forgotten; Mahony's k_P = a_n / dt). At the floor a white reading noise
of deviation σ leaves ``σ √(a / (2 − a))`` = 0.05 σ in the estimate. Without noise the estimate
stays on the reading: the gyro's mean rate over each period composes to the base's rotation
(``JointState``). Simplified: no gyro-bias integral (the simulated gyro has none; a real IMU's is
estimated by its own attitude filter before the reading reaches us).

The task's frame is the robot's pose at the start, as its sensors tell it: ``start_attitude`` is
the estimate carried back to the first reading by the gyro's rotation since then, so that every
reading until now refines it (the first reading alone is off by the attitude noise: 0.5° of
heading puts a drawer 3.3 m ahead 3 cm to the side).

Why: the controller's feedback (the balance stabilizer on the DCM, the hands' measured-position
corrections, the grasp's switching conditions) differentiates or thresholds what the sensors say;
0.5° of attitude noise moves the estimated CoM by 8 mm and a hand by 5 mm from one tick to the next.
The joint encoders are left as they are: their velocities, sampled once per period, misrepresent
the stiff leg servos' motion within it, and a filter carried forward by them ran up to 11 mrad off
the ankles' readings without any noise.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from robot_ctrl.geometry import yaw_of
from robot_ctrl.hw.types import JointState

#: [s] the time constant τ (gain floor dt / τ)
TIME_CONSTANT = 1.0

#: [s] a gap between states longer than this restarts the filter on the reading
RESTART_GAP = 0.1


def attitude_step(previous: np.ndarray, turn: np.ndarray, reading: np.ndarray, gain: float) -> np.ndarray:
    """``R̂_k = P Exp(a Log(Pᵀ R_k))`` with ``P = R̂_{k−1} ΔR``: rotation matrices, ``ΔR = Exp(dt ω̄_k)``
    the gyro's turn over the tick, ω̄_k its mean rate over it in the body frame (``JointState``;
    Mahony et al. 2008, eq. 13, k_I = 0)."""
    predicted = previous @ turn
    return predicted @ pin.exp3(gain * pin.log3(predicted.T @ reading))


class AttitudeFilter:
    def __init__(self, time_constant: float = TIME_CONSTANT):
        if not time_constant > 0:
            raise ValueError(f"attitude filter time constant = {time_constant} s must be > 0")
        self.time_constant = time_constant
        self._t: float | None = None  # time of the last reading [s]
        self._n = 0  # readings since the filter (re)started
        self._attitude: np.ndarray | None = None  # the estimate (world from base)
        self._turned = np.eye(3)  # the gyro's rotation since the first reading (start base from base)
        self._start_position: np.ndarray | None = None  # the base position of the first reading [m]
        self._start_pose: np.ndarray | None = None  # start_pose since the last reading (asked for many times a tick)

    @property
    def start_attitude(self) -> np.ndarray | None:
        """The base orientation at the first reading (world from base), refined by every reading since."""
        return None if self._attitude is None else self._attitude @ self._turned.T

    @property
    def start_pose(self) -> np.ndarray | None:
        """World (x, y, yaw) of the base at the first reading, its yaw from ``start_attitude``."""
        if self._start_pose is None:
            attitude = self.start_attitude
            if attitude is None or self._start_position is None:
                return None
            self._start_pose = np.array([*self._start_position[:2], yaw_of(attitude)])
            self._start_pose.flags.writeable = False  # shared by every caller until the next reading
        return self._start_pose

    def update(self, state: JointState) -> JointState:
        """``state`` with its base orientation replaced by the filtered estimate."""
        if state.base_quat_xyzw is None:
            return state
        reading = _matrix(state.base_quat_xyzw)
        self._start_pose = None
        dt = 0.0 if self._t is None else state.t - self._t
        self._t = state.t
        if self._attitude is None or state.base_angvel is None or not 0.0 < dt <= RESTART_GAP:
            self._n, self._attitude, self._turned = 1, reading, np.eye(3)
            self._start_position = None if state.base_pos is None else np.array(state.base_pos, dtype=float)
            return state
        self._n += 1
        turn = pin.exp3(dt * np.asarray(state.base_angvel))  # the gyro's mean over the period
        self._turned = self._turned @ turn
        self._attitude = attitude_step(self._attitude, turn, reading,
                                       max(1.0 / self._n, min(1.0, dt / self.time_constant)))
        x, y, z, w = pin.Quaternion(self._attitude).coeffs()
        return dataclasses.replace(state, base_quat_xyzw=np.array([x, y, z, w]))


def _matrix(quat_xyzw: np.ndarray) -> np.ndarray:
    x, y, z, w = quat_xyzw
    return pin.Quaternion(w, x, y, z).normalized().matrix()
