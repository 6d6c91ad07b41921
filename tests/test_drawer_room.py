"""The drawer anywhere in a room: the cabinet's pose on the command line, the room's walls, the
planned approach round the cabinet to the hand-over pose, and one full run at an oblique pose."""

import json

import mujoco
import numpy as np
import pytest

from robot_ctrl.cli import main
from robot_ctrl.geometry.drawer_geometry import DRAWER_READINGS, DrawerGeometry
from robot_ctrl.geometry.room import AXIS_ANGLE, Box, CabinetPose, Room, plan_approach
from robot_ctrl.hw.types import JointCommand
from robot_ctrl.robot.model import load_robot
from robot_ctrl.sim.drawer_cabinet import DrawerPlacement
from robot_ctrl.sim.mujoco_backend import MujocoBackend

GEOMETRY = DrawerGeometry()
HANDOVER = 1.65  # [m] Talos's: its comfort distance and the geometry's handover_walk


def clearance_from(box: Box, p: np.ndarray) -> float:
    """Distance [m] of the point ``p`` from the rectangle ``box`` (0 inside)."""
    dx = max(box.x0 - p[0], 0.0, p[0] - box.x1)
    dy = max(box.y0 - p[1], 0.0, p[1] - box.y1)
    return float(np.hypot(dx, dy))


@pytest.mark.parametrize("pose,free", [((2.5, 0.0, 0.0), True), ((-3.0, 0.0, 0.0), False), ((0.0, 2.5, -90.0), False),
                                       ((1.6, -1.2, 120.0), False), ((2.0, 2.0, 270.0), False),
                                       ((-2.5, 1.0, 0.0), False), ((2.5, 0.0, 90.0), True)])
def test_the_path_keeps_clear_of_the_cabinet_and_the_walls_and_comes_in_facing_it(pose, free):
    cabinet = CabinetPose(pose[0], pose[1], np.radians(pose[2]))
    radius = GEOMETRY.body_radius
    plan = plan_approach(cabinet, GEOMETRY.footprint(), Room(against_wall=not free), radius, HANDOVER)
    # Every point of the path, in the cabinet's frame: the robot's radius off the cabinet and the walls.
    local = cabinet.from_start(plan.waypoints)
    points = np.concatenate([a + np.linspace(0, 1, 50)[:, None] * (b - a) for a, b in zip(local, local[1:])])
    assert min(clearance_from(GEOMETRY.footprint(), p) for p in points) >= radius - 1e-9
    assert all(plan.interior.grown(-radius).contains(p) for p in points)
    # It ends at the hand-over pose on the cabinet's axis, facing the cabinet, coming in along the axis.
    np.testing.assert_allclose(local[-1], [-HANDOVER, 0.0], atol=1e-9)
    assert np.isclose(plan.handover[2], cabinet.yaw) and np.allclose(plan.handover[:2], plan.waypoints[-1])
    last = local[-1] - local[-2]
    assert abs(np.arctan2(last[1], last[0])) <= AXIS_ANGLE + 1e-9
    # The walls are the room's: four, round the interior, every start-frame corner inside them.
    assert len(plan.walls) == 4 and plan.interior.contains(cabinet.from_start(np.zeros(2)))


def test_a_cabinet_behind_another_way_round_is_walked_round():
    """Facing away, straight ahead: the way to its front passes beside it, not through it."""
    cabinet = CabinetPose(2.5, 0.0, 0.0)
    plan = plan_approach(cabinet, GEOMETRY.footprint(), Room(against_wall=False), GEOMETRY.body_radius, HANDOVER)
    assert len(plan.waypoints) >= 4 and plan.length > 2 * 2.5
    assert abs(plan.waypoints[:, 1]).max() >= GEOMETRY.footprint().y1 + GEOMETRY.body_radius


def test_a_cabinet_straight_ahead_facing_the_robot_is_the_task_without_a_room_walk():
    plan = plan_approach(CabinetPose(2.0, 0.0, np.pi), GEOMETRY.footprint(), Room(), GEOMETRY.body_radius, HANDOVER)
    assert not plan.walks and plan.handover_distance == 2.0 and np.allclose(plan.handover, 0.0)


@pytest.mark.parametrize("pose,room,message", [
    ((1.0, 0.0, 180.0), Room(), "the front panel is 1.00 m from the start"),
    ((4.5, 4.5, 180.0), Room(), "the front panel is 6.36 m from the start"),
    ((2.13, -0.77, 2.0), Room(), "the start is not inside the 6 x 6 m room"),
    ((1.3, 0.8, 180.0), Room(depth=2.5), "the room leaves no 1.65 m in front of the cabinet"),
])
def test_a_cabinet_whose_front_cannot_be_reached_says_why(pose, room, message):
    with pytest.raises(ValueError, match=message):
        plan_approach(CabinetPose(pose[0], pose[1], np.radians(pose[2])), GEOMETRY.footprint(), room,
                      GEOMETRY.body_radius, HANDOVER)


def test_a_moved_cabinet_is_walked_to_from_where_the_robot_is_inside_the_room_as_it_stands():
    first = CabinetPose(-2.5, 1.0, 0.0)
    plan = plan_approach(first, GEOMETRY.footprint(), Room(), GEOMETRY.body_radius, HANDOVER)
    moved = CabinetPose(-2.0, -1.5, np.radians(30.0))
    here = np.array([-0.2, 0.3])
    again = plan_approach(moved, GEOMETRY.footprint(), Room(), GEOMETRY.body_radius, HANDOVER, start=here,
                          placed=plan.room)
    # The room stays: the same walls, its inside still the first cabinet's frame's box.
    assert again.walls == plan.walls and again.room == plan.room
    # From the robot, clear of the moved cabinet and of the walls, into the moved cabinet's hand-over pose.
    np.testing.assert_allclose(again.waypoints[0], here)
    local = moved.from_start(again.waypoints)
    points = np.concatenate([a + np.linspace(0, 1, 50)[:, None] * (b - a) for a, b in zip(local, local[1:])])
    assert min(clearance_from(GEOMETRY.footprint(), p) for p in points) >= GEOMETRY.body_radius - 1e-9
    assert all(plan.room.holds(p, GEOMETRY.body_radius) for p in moved.to_start(points))
    np.testing.assert_allclose(local[-1], [-HANDOVER, 0.0], atol=1e-9)
    assert np.isclose(again.handover[2], moved.yaw)
    # Placed afresh round the moved cabinet, the room would be another one: the jump does not move walls.
    assert plan_approach(moved, GEOMETRY.footprint(), Room(), GEOMETRY.body_radius, HANDOVER).walls != plan.walls
    with pytest.raises(ValueError, match="the cabinet overlaps the robot's path"):
        plan_approach(moved, GEOMETRY.footprint(), Room(), GEOMETRY.body_radius, HANDOVER,
                      start=moved.to_start(np.array([-0.2, 0.0])), placed=plan.room)


def test_a_cabinet_on_the_robot_is_refused():
    with pytest.raises(ValueError, match="overlaps the robot's start"):
        plan_approach(CabinetPose(1.3, 0.0, np.pi), GEOMETRY.footprint(), Room(), 1.5, HANDOVER)


@pytest.mark.parametrize("args,message", [
    (["--cabinet", "3,1"], "--cabinet '3,1' must be X,Y,YAW_DEG, 3 finite numbers"),
    (["--cabinet", "3,nan,0"], "--cabinet '3,nan,0' must be X,Y,YAW_DEG"),
    (["--cabinet", "1.0,0.2,180"], "--cabinet = 1,0.2,180: the front panel is 1.02 m from the start: allowed 1.2-6"),
    (["--cabinet", "2.13,-0.77,2"], "--cabinet = 2.13,-0.77,2: the start is not inside the 6 x 6 m room"),
    (["--cabinet", "3,1,200", "--room", "1,6"], "--room width = 1 m is outside the allowed range [2, 20] m"),
    (["--room", "8,8"], "--room and --free-standing need --cabinet"),
    (["--cabinet", "3,1,200", "--goal-jump", "2:3.5"],
     "--goal-jump distance = 3.5 m: a cabinet the robot walks round to moves to a pose (TIME:X,Y,YAW_DEG)"),
    (["--distance", "2", "--goal-jump", "2:2.5,1,90"], "--goal-jump pose = 2.5,1,90: a pose moves a cabinet the robot "
                                                       "walks round to (--cabinet)"),
    (["--cabinet=-2.5,1.0,0", "--goal-jump", "3:2.5,1"], "--goal-jump '3:2.5,1' must be TIME:X,Y,YAW_DEG in a room"),
    (["--cabinet=-2.5,1.0,0", "--goal-jump", "30:-2.5,-0.8,0"],
     "--goal-jump time = 30 s is outside the allowed range (0, 9.1] s (while the robot surely still walks"),
    (["--cabinet=-2.5,1.0,0", "--goal-jump", "2:-1.2,0.4,0"],
     "--goal-jump pose = -1.2,0.4,0: the cabinet would land on the robot's path"),
    (["--cabinet=-2.5,1.0,0", "--goal-jump", "2:-2.5,-2.8,0"],
     "--goal-jump pose = -2.5,-2.8,0: the cabinet does not fit inside the room where it stands"),
    (["--cabinet=-2.5,1.0,0", "--goal-jump", "2:-2.5,-0.8,0", "--goal-jump", "3:-2.5,-1.0,0"],
     "--goal-jump pose = -2.5,-1,0: a cabinet in a room moves once (2 jumps)"),
    (["--cabinet", "3,1,200", "--method", "naive"], "--method = naive walks straight in"),
])
def test_drawer_rejects_a_cabinet_it_cannot_reach(args, message, capsys, tmp_path):
    assert main(["drawer", *args, "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "run").exists()


def test_the_room_walls_stand_where_planned_and_collide():
    robot = load_robot("talos")
    cabinet = CabinetPose(-2.5, 1.0, 0.0)
    plan = plan_approach(cabinet, GEOMETRY.footprint(), Room(), GEOMETRY.body_radius, HANDOVER)
    placement = DrawerPlacement(plan.handover_distance, "front_left", frame=tuple(plan.handover), walls=plan.walls)
    backend = MujocoBackend(robot, prop=placement)
    backend.configure()
    backend.activate()
    m, d = backend.m, backend.d
    start = d.xpos[m.body("talos/base_link").id][:2].copy()  # the start frame: the robot at the origin, heading x
    inside = plan.interior.corners()
    for i in range(4):
        geom = m.geom(f"wall_{i}")
        assert geom.contype[0] == 1 and geom.rgba[3] == 1.0 and geom.rbound[0] > 1.0
    # Each inside corner lies on the inner faces of two walls, and the cabinet's panel at its pose.
    faces = []
    for i in range(4):
        geom = m.geom(f"wall_{i}")
        centre, rot, half = d.geom_xpos[geom.id][:2] - start, d.geom_xmat[geom.id].reshape(3, 3)[:2, :2], geom.size[:2]
        faces.append((centre, rot, half))
    for corner in cabinet.to_start(inside):
        local = [rot.T @ (corner - centre) for centre, rot, _ in faces]
        touching = [abs(abs(p[1]) - half[1]) < 2e-3 and abs(p[0]) <= half[0] for p, (_, _, half) in zip(local, faces)]
        assert sum(touching) == 2, corner
    panel = d.xpos[m.body("cabinet").id][:2] - start
    np.testing.assert_allclose(panel, [cabinet.x, cabinet.y], atol=2e-3)
    # A wall moved onto the standing robot is felt, as any furniture.
    q = np.array(robot.config.half_sitting)
    command = JointCommand(q, np.zeros(robot.nj), robot.kp, robot.kd, np.zeros(robot.nj))
    backend.write(command)
    assert dict(zip(DRAWER_READINGS, backend.read().scene))["unintended_contacts"] == 0.0
    d.mocap_pos[m.body("wall_0").mocapid[0]] = [start[0], start[1] + 0.1, 0.0]
    d.mocap_quat[m.body("wall_0").mocapid[0]] = [1.0, 0.0, 0.0, 0.0]
    mujoco.mj_forward(m, d)
    backend.write(command)
    touch = dict(zip(DRAWER_READINGS, backend.read().scene))
    assert touch["unintended_contacts"] > 0 and touch["unintended_force_n"] > 1.0
    backend.close()


def test_without_a_room_the_walls_neither_show_nor_collide():
    backend = MujocoBackend(load_robot("talos"), prop=DrawerPlacement(2.0, "front_left"))
    backend.configure()
    backend.activate()
    for i in range(4):
        geom = backend.m.geom(f"wall_{i}")
        assert geom.contype[0] == geom.conaffinity[0] == 0 and geom.rgba[3] == 0.0
    backend.close()


def test_the_drawer_at_an_oblique_pose_behind_the_robot(tmp_path):
    """The cabinet 2.7 m behind and to the left, facing the robot's line: the robot turns on the
    spot, walks to the cabinet's axis, stops facing it; the synthesis takes over with its normal,
    short and standing actions and lands the pelvis at the comfort distance."""
    status = main(["drawer", "--cabinet=-2.5,1.0,0", "--slot", "front_left", "--quiet", "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["fell"] is False and report["success"] is True
    approach = report["approach"]
    assert approach["planned_path_m"][0] == [0.0, 0.0] and len(approach["planned_path_m"]) >= 2
    assert approach["handover_pose"][2] in (180.0, -180.0)
    handover = approach["handover_error"]
    assert abs(handover["along_m"]) < 0.06 and abs(handover["lateral_m"]) < 0.06 and abs(handover["yaw_deg"]) < 5
    # The feet, where the pelvis sways from: within a centimetre of the hand-over pose, facing it.
    assert abs(handover["stance_along_m"]) < 0.01 and abs(handover["stance_lateral_m"]) < 0.01
    assert abs(handover["stance_yaw_deg"]) < 2
    # The walked path follows the planned one, and the robot ends on the cabinet's axis, facing it.
    walked = np.array(approach["realized_path_m"])
    assert np.linalg.norm(walked[int(approach["handover_time_s"] / 0.25)] - approach["handover_pose"][:2]) < 0.08
    assert report["actions"][-2:] == [2, 3] and 1 in report["actions"]
    assert abs(report["final_pelvis_to_drawer_m"] - report["comfort_distance_m"]) <= 0.03
    assert abs(report["final_pelvis_lateral_m"]) <= 0.03 and abs(report["final_pelvis_yaw_error_deg"]) <= 5
    assert report["grasp"] == "contact" and report["grasp_time_s"] > approach["handover_time_s"]
    assert report["safety"]["interventions"] == {}
    assert report["room"]["against_wall"] is True and len(report["room"]["corners_m"]) == 4
    page = (tmp_path / "report.html").read_text()
    assert page.count("data:image/png;base64,") >= 6


def test_a_cabinet_that_moves_during_the_approach_is_walked_to_where_it_went(tmp_path):
    """At 4 s, while the robot walks to the cabinet's front at (2, 2) facing -y, the cabinet jumps to
    (2.5, -1) facing 150°: the robot plans its path again from where it is, inside the room as it
    stands, and the synthesis lands the pelvis at the comfort distance of the moved cabinet."""
    status = main(["drawer", "--cabinet=2.0,2.0,270", "--goal-jump", "4:2.5,-1.0,150", "--slot", "front_left",
                   "--quiet", "--no-html", "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["fell"] is False and report["success"] is True
    assert report["cabinet_moves"][0]["time_s"] == 4.0 and report["cabinet_moves"][0]["front_yaw_deg"] == 150.0
    approach = report["approach"]
    (again,) = approach["replanned"]
    assert again["time_s"] == 4.0 and approach["failed"] is None
    # Planned again from where the robot was then, to the moved cabinet's hand-over pose.
    walked = np.array(approach["realized_path_m"])
    assert np.linalg.norm(walked[int(4.0 / 0.25)] - again["planned_path_m"][0]) < 0.1
    moved = CabinetPose(2.5, -1.0, np.radians(150.0))
    handover = moved.to_start(np.array([-report["approach"]["handover_distance_m"], 0.0]))
    np.testing.assert_allclose(again["planned_path_m"][-1], handover, atol=1e-3)
    assert approach["handover_pose"][2] == pytest.approx(-30.0)
    # The pelvis ends against the moved cabinet: at the comfort distance, on its axis, facing it.
    assert abs(report["final_pelvis_to_drawer_m"] - report["comfort_distance_m"]) <= 0.03
    assert abs(report["final_pelvis_lateral_m"]) <= 0.03 and abs(report["final_pelvis_yaw_error_deg"]) <= 5
    assert report["step_length_error_max_m"] <= 0.010 and report["grasp"] == "contact"
    assert report["safety"]["interventions"] == {}
