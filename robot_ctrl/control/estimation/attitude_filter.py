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

import math

import numpy as np
import pinocchio as pin

from robot_ctrl.geometry import yaw_of
from robot_ctrl.hw.types import JointState
from robot_ctrl.kernels import FLOAT, VECTOR, kernel

#: [s] the time constant τ (gain floor dt / τ)
TIME_CONSTANT = 1.0

#: [s] a gap between states longer than this restarts the filter on the reading
RESTART_GAP = 0.1

IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])  # quaternion (x, y, z, w)


@kernel((VECTOR, VECTOR, VECTOR, VECTOR, FLOAT, FLOAT))
def attitude_step(previous: np.ndarray, turned: np.ndarray, reading: np.ndarray, rate: np.ndarray, dt: float,
                  gain: float) -> tuple[np.ndarray, np.ndarray]:
    """``R̂_k = P Exp(a Log(Pᵀ R_k))`` with ``P = R̂_{k−1} ΔR``, ``ΔR = Exp(dt ω̄_k)`` the gyro's turn
    over the tick, ω̄_k (``rate``) its mean rate over it in the body frame (``JointState``; Mahony et
    al. 2008, eq. 13, k_I = 0), in unit quaternions (x, y, z, w): ``previous`` R̂_{k−1}, ``reading``
    R_k (normalized here), ``turned`` the gyro's rotation so far. Returns ``(R̂_k, turned ΔR)``.
    Compiled: it runs on every tick, where Pinocchio's and numpy's per-call costs are most of it."""
    turn = _quat_exp(dt * rate[0], dt * rate[1], dt * rate[2])
    predicted = _quat_mul(previous, turn)
    r = reading / math.sqrt(reading @ reading)
    error = _quat_mul(np.array([-predicted[0], -predicted[1], -predicted[2], predicted[3]]), r)
    ex, ey, ez = _quat_log(error)
    estimate = _quat_mul(predicted, _quat_exp(gain * ex, gain * ey, gain * ez))
    estimate /= math.sqrt(estimate @ estimate)
    return (estimate if estimate[3] >= 0.0 else -estimate), _quat_mul(turned, turn)


@kernel()
def _quat_mul(a, b):
    """Hamilton product ``a b`` of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a[0], a[1], a[2], a[3]
    bx, by, bz, bw = b[0], b[1], b[2], b[3]
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


@kernel()
def _quat_exp(x, y, z):
    """``Exp`` of the rotation vector (x, y, z) [rad]: ``(sin(θ/2) u, cos(θ/2))``, θ u = (x, y, z)."""
    theta = math.sqrt(x * x + y * y + z * z)
    k = 0.5 - theta * theta / 48.0 if theta < 1e-4 else math.sin(0.5 * theta) / theta  # sin(θ/2) / θ
    return np.array([k * x, k * y, k * z, math.cos(0.5 * theta)])


@kernel()
def _quat_log(q):
    """``Log`` of a unit quaternion (x, y, z, w): the rotation vector θ u of the shorter way round
    (θ ≤ π), with ``θ = 2 atan2(|v|, |w|)``; well defined at 0 (θ / |v| → 2 / |w|) and at π."""
    sign = 1.0 if q[3] >= 0.0 else -1.0
    x, y, z, w = sign * q[0], sign * q[1], sign * q[2], sign * q[3]
    n = math.sqrt(x * x + y * y + z * z)
    k = 2.0 * math.atan2(n, w) / n if n > 1e-12 else 2.0 / w
    return k * x, k * y, k * z


class AttitudeFilter:
    def __init__(self, time_constant: float = TIME_CONSTANT):
        if not time_constant > 0:
            raise ValueError(f"attitude filter time constant = {time_constant} s must be > 0")
        self.time_constant = time_constant
        self._t: float | None = None  # time of the last reading [s]
        self._n = 0  # readings since the filter (re)started
        self._attitude: np.ndarray | None = None  # the estimate (world from base), quaternion (x, y, z, w)
        self._turned = IDENTITY  # the gyro's rotation since the first reading (start base from base), the same
        self._start_position: np.ndarray | None = None  # the base position of the first reading [m]
        self._start_pose: np.ndarray | None = None  # start_pose since the last reading (asked for many times a tick)

    @property
    def start_attitude(self) -> np.ndarray | None:
        """The base orientation at the first reading (world from base), refined by every reading since."""
        return None if self._attitude is None else _matrix(self._attitude) @ _matrix(self._turned).T

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
        reading = np.asarray(state.base_quat_xyzw, dtype=float)
        self._start_pose = None
        dt = 0.0 if self._t is None else state.t - self._t
        self._t = state.t
        if self._attitude is None or state.base_angvel is None or not 0.0 < dt <= RESTART_GAP:
            self._n, self._attitude, self._turned = 1, reading / np.linalg.norm(reading), IDENTITY
            self._start_position = None if state.base_pos is None else np.array(state.base_pos, dtype=float)
            return state
        self._n += 1
        self._attitude, self._turned = attitude_step(self._attitude, self._turned, reading,
                                                     np.asarray(state.base_angvel, dtype=float), dt,
                                                     max(1.0 / self._n, min(1.0, dt / self.time_constant)))
        return state.replaced(base_quat_xyzw=self._attitude.copy())


def _matrix(quat_xyzw: np.ndarray) -> np.ndarray:
    x, y, z, w = quat_xyzw
    return pin.Quaternion(w, x, y, z).normalized().matrix()
