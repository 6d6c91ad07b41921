"""WalkLog: the time series of a walk and the balance metrics users judge a walking controller by.

Recorded every control tick (world frame unless said otherwise): the reference ZMP of the plan,
the ZMP measured from the foot force/torque readings, planned and measured CoM, the plan's
heading, the stance foot in single support, and each foot's vertical ground reaction force.
Metrics (``metrics()``):

- ``zmp_error_rms_m`` / ``zmp_error_max_m``: measured − reference ZMP over single-support samples,
  ``{"x": along the heading, "y": lateral}`` (thesis Fig. 3.43);
- ``zmp_lateral_std_m``: per stance foot, the standard deviation of the measured ZMP's lateral
  position in that sole's frame over its single-support samples (thesis Fig. 3.46);
- ``com_error_rms_m`` / ``com_error_max_m``: horizontal distance between measured and planned CoM;
- ``grf_limit_n``: the vertical ground-reaction-force limit per foot, ``grf_limit_ratio`` × weight
  (default 1.4: HRP-2's 800 N over its weight); ``grf_over_limit`` says whether a foot exceeded it.

``save(dir)`` writes ``dir/timeseries.npz`` for ``robot-ctrl report``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from robot_ctrl.geometry import SIDES

GRF_LIMIT_RATIO = 1.4


class WalkLog:
    def __init__(self, weight: float, start_pose: np.ndarray, foot_size: tuple[float, float],
                 grf_limit_ratio: float = GRF_LIMIT_RATIO):
        """``start_pose``: world (x, y, yaw) of the start frame the report's footsteps use;
        ``foot_size``: sole (length, width) [m], for drawing footprints."""
        if not (np.isfinite(grf_limit_ratio) and grf_limit_ratio > 0):
            raise ValueError(f"grf_limit_ratio = {grf_limit_ratio} must be > 0")
        self.grf_limit = grf_limit_ratio * weight  # [N]
        self.start_pose = np.asarray(start_pose, dtype=float)
        self.foot_size = foot_size
        self.rows: list[tuple] = []

    def record(self, t: float, zmp_ref: np.ndarray, zmp: np.ndarray | None, com_ref: np.ndarray, com: np.ndarray,
               heading: float, stance: str | None, stance_sole: tuple[np.ndarray, float] | None,
               grf: dict[str, float]) -> None:
        """One tick. ``stance``: the single-support foot (None in double support or standing);
        ``stance_sole``: that sole's world (xy, yaw)."""
        measured = zmp if zmp is not None else (np.nan, np.nan)
        sole = stance_sole if stance_sole is not None else ((np.nan, np.nan), np.nan)
        self.rows.append((t, *zmp_ref, *measured, *com_ref[:2], *com[:2], heading,
                          SIDES.index(stance) if stance in SIDES else -1, *sole[0], sole[1],
                          grf.get("left", 0.0), grf.get("right", 0.0)))

    def arrays(self) -> dict[str, np.ndarray]:
        a = np.array(self.rows, dtype=float).reshape(-1, 16)
        return {"t": a[:, 0], "zmp_ref": a[:, 1:3], "zmp": a[:, 3:5], "com_ref": a[:, 5:7], "com": a[:, 7:9],
                "heading": a[:, 9], "stance": a[:, 10].astype(int), "stance_sole_xy": a[:, 11:13],
                "stance_sole_yaw": a[:, 13], "grf": a[:, 14:16]}

    def metrics(self) -> dict:
        a = self.arrays()
        single = (a["stance"] >= 0) & np.all(np.isfinite(a["zmp"]), axis=1)
        out = {}
        if single.any():
            local = _in_frame(a["zmp"][single] - a["zmp_ref"][single], a["heading"][single])
            out["zmp_error_rms_m"] = {k: round(float(np.sqrt(np.mean(local[:, i] ** 2))), 5) for i, k in enumerate("xy")}
            out["zmp_error_max_m"] = {k: round(float(np.abs(local[:, i]).max()), 5) for i, k in enumerate("xy")}
            lateral = {}
            for index, side in enumerate(SIDES):
                rows = single & (a["stance"] == index)
                if rows.sum() > 1:
                    sole_y = _in_frame(a["zmp"][rows] - a["stance_sole_xy"][rows], a["stance_sole_yaw"][rows])[:, 1]
                    lateral[side] = round(float(np.std(sole_y)), 5)
            out["zmp_lateral_std_m"] = lateral
        com_err = np.linalg.norm(a["com"] - a["com_ref"], axis=1)
        out["com_error_rms_m"] = round(float(np.sqrt(np.mean(com_err**2))), 5) if len(com_err) else None
        out["com_error_max_m"] = round(float(com_err.max()), 5) if len(com_err) else None
        out["grf_limit_n"] = round(self.grf_limit, 2)
        out["grf_over_limit"] = {side: bool(a["grf"][:, i].max() > self.grf_limit) if len(a["grf"]) else False
                                 for i, side in enumerate(SIDES)}
        return out

    def save(self, out_dir: Path) -> Path:
        path = Path(out_dir) / "timeseries.npz"
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, grf_limit_n=self.grf_limit, start_pose=self.start_pose,
                            foot_size=np.asarray(self.foot_size), **self.arrays())
        return path


def _in_frame(vectors: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """World vectors (n, 2) expressed in frames rotated by ``yaw`` (n,): ``R(yaw)ᵀ v``."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * vectors[:, 0] + s * vectors[:, 1], -s * vectors[:, 0] + c * vectors[:, 1]], axis=1)


def step_length_errors(footsteps: list[dict]) -> list[float]:
    """Realized − planned length [m] of each step (distance from the previous footstep), from the
    walk report's footsteps (start frame (x, y, yaw) planned and realized)."""
    out = []
    for prev, step in zip(footsteps, footsteps[1:]):
        planned = np.linalg.norm(np.subtract(step["planned"][:2], prev["planned"][:2]))
        realized = np.linalg.norm(np.subtract(step["realized"][:2], prev["realized"][:2]))
        out.append(round(float(realized - planned), 5))
    return out
