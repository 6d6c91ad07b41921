"""WalkLog's figures from synthetic ticks of a known answer (no physics run): ZMP errors in the
heading frame over single support only, the lateral ZMP spread in each sole's frame, CoM errors,
the GRF limit, and what ``save`` writes for ``robot-ctrl report``."""

from __future__ import annotations

import numpy as np
import pytest

from robot_ctrl.eval.recording.walk_log import WalkLog

WEIGHT = 900.0  # [N]
SOLE = (0.2, 0.1)
QUARTER = np.pi / 2


def walk_log() -> WalkLog:
    """Heading +90° (walking along world y). Left stance: sole at (1, 0.1) turned +90°; right stance:
    sole at (1.2, −0.1) turned −90°. Measured ZMP errors against the plan, in the heading frame: +3 cm
    along, then −4 cm along and +1 cm lateral, then (right stance) −20 cm along and −21 cm lateral; a
    double-support tick and a tick without a measured ZMP do not count."""
    log = WalkLog(WEIGHT, np.array([0.5, -0.5, 0.1]), SOLE)
    ref = np.array([1.0, 0.1])
    left = (np.array([1.0, 0.1]), QUARTER)
    right = (np.array([1.2, -0.1]), -QUARTER)
    com = np.array([0.9, 0.0, 0.8])
    # heading +90°: along = world +y, lateral (heading frame y) = world −x
    log.record(0.000, ref, ref + [0.0, 0.03], com, com + [0.003, 0.004, 0.0], QUARTER, "left", left,
               {"left": 800.0, "right": 0.0})
    log.record(0.005, ref, ref + [-0.01, -0.04], com, com + [0.0, 0.012, 0.0], QUARTER, "left", left,
               {"left": 1.4 * WEIGHT, "right": 0.0})
    log.record(0.010, ref, ref + [0.5, 0.5], com, com, QUARTER, None, None, {"left": 400.0, "right": 400.0})
    log.record(0.015, ref, None, com, com, QUARTER, "right", right, {"right": 1.4 * WEIGHT + 1.0})
    log.record(0.020, ref, np.array([1.21, -0.1]), com, com, QUARTER, "right", right, {"left": 500.0})
    return log


def test_zmp_errors_are_taken_along_and_across_the_heading_over_single_support_only():
    m = walk_log().metrics()
    # errors (along, lateral): (0.03, 0), (−0.04, 0.01) and, right stance, (−0.2, −0.21)
    along, lateral = np.array([0.03, -0.04, -0.2]), np.array([0.0, 0.01, -0.21])
    assert m["zmp_error_rms_m"] == {"x": round(float(np.sqrt(np.mean(along**2))), 5),
                                    "y": round(float(np.sqrt(np.mean(lateral**2))), 5)}
    assert m["zmp_error_max_m"] == {"x": 0.2, "y": 0.21}


def test_the_lateral_zmp_spread_is_measured_in_each_stance_sole_frame():
    m = walk_log().metrics()
    # Left sole turned +90°: its lateral axis is world −x; the ZMP sat at 0 and at +0.01 on it.
    assert m["zmp_lateral_std_m"] == {"left": 0.005}  # the right foot has one sample: no spread


def test_com_errors_and_the_grf_limit():
    m = walk_log().metrics()
    errors = np.array([0.005, 0.012, 0.0, 0.0, 0.0])
    assert m["com_error_rms_m"] == round(float(np.sqrt(np.mean(errors**2))), 5) and m["com_error_max_m"] == 0.012
    assert m["grf_limit_n"] == 1260.0
    assert m["grf_over_limit"] == {"left": False, "right": True}  # at the limit is not over it


def test_an_empty_log_has_no_zmp_figures_and_the_ratio_is_checked():
    m = WalkLog(WEIGHT, np.zeros(3), SOLE, grf_limit_ratio=2.0).metrics()
    assert m == {"com_error_rms_m": None, "com_error_max_m": None, "grf_limit_n": 1800.0,
                 "grf_over_limit": {"left": False, "right": False}}
    assert WalkLog(WEIGHT, np.zeros(3), SOLE, grf_limit_ratio=0.5).metrics()["grf_limit_n"] == 450.0
    for ratio in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match=f"grf_limit_ratio = {ratio} must be > 0"):
            WalkLog(WEIGHT, np.zeros(3), SOLE, grf_limit_ratio=ratio)


def test_save_writes_every_series_for_the_report(tmp_path):
    log = walk_log()
    path = log.save(tmp_path / "run")
    assert path == tmp_path / "run" / "timeseries.npz"
    with np.load(path) as f:
        assert float(f["grf_limit_n"]) == 1260.0 and f["start_pose"].tolist() == [0.5, -0.5, 0.1]
        assert f["foot_size"].tolist() == list(SOLE)
        np.testing.assert_allclose(f["t"], [0.0, 0.005, 0.01, 0.015, 0.02])
        assert f["stance"].tolist() == [0, 0, -1, 1, 1]
        np.testing.assert_allclose(f["zmp"][1], [0.99, 0.06])
        assert np.all(np.isnan(f["zmp"][3])) and np.all(np.isnan(f["stance_sole_xy"][2]))
        np.testing.assert_allclose(f["zmp_ref"][0], [1.0, 0.1])
        np.testing.assert_allclose(f["com_ref"][0], [0.9, 0.0])
        np.testing.assert_allclose(f["com"][1], [0.9, 0.012])
        np.testing.assert_allclose(f["heading"], QUARTER)
        np.testing.assert_allclose(f["stance_sole_xy"][4], [1.2, -0.1])
        np.testing.assert_allclose(f["stance_sole_yaw"][[0, 4]], [QUARTER, -QUARTER])
        np.testing.assert_allclose(f["grf"][:, 0], [800.0, 1260.0, 400.0, 0.0, 500.0])  # a foot not given: 0 N
        np.testing.assert_allclose(f["grf"][:, 1], [0.0, 0.0, 400.0, 1261.0, 0.0])
    log.save(tmp_path / "run")  # again, over the first
    assert log.save(tmp_path / "a" / "b").is_file()  # folders made as needed


def test_errors_in_frames_turned_at_any_angle_and_the_figures_rounding():
    """Heading and sole both turned 0.5 rad: errors given in those frames come back as given, rounded
    to 0.01 mm; the GRF limit to 0.01 N."""
    log = WalkLog(901.234, np.zeros(3), SOLE)
    yaw = 0.5
    turn = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    ref = np.array([0.25, 0.1])
    for along, lateral, in_sole in ((0.0123456, -0.0065432, 0.0111111), (-0.0023456, 0.0034567, 0.0322222)):
        zmp = ref + turn @ [along, lateral]
        stance_sole = (zmp - turn @ [0.0, in_sole], yaw)  # the ZMP in_sole to the sole's left
        log.record(0.0, ref, zmp, np.zeros(3), np.array([0.0123456, 0.0, 0.0]), yaw, "left", stance_sole, {})
    m = log.metrics()
    assert m["zmp_error_max_m"] == {"x": 0.01235, "y": 0.00654}
    assert m["zmp_error_rms_m"] == {"x": round(float(np.sqrt((0.0123456**2 + 0.0023456**2) / 2)), 5),
                                    "y": round(float(np.sqrt((0.0065432**2 + 0.0034567**2) / 2)), 5)}
    assert m["zmp_lateral_std_m"] == {"left": 0.01056}  # std of 0.0111111 and 0.0322222
    assert m["com_error_max_m"] == 0.01235 and m["grf_limit_n"] == 1261.73
