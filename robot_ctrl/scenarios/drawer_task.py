"""DrawerTask: what a user asks of the drawer scenario (where the cabinet stands, which slot holds
the object, the cabinet's jumps, the speed class, the dynamic filter, the control period, how the
base is seen), and its check against what the learned primitives can do."""

from __future__ import annotations

from dataclasses import dataclass

from robot_ctrl.control.commanders.approach_walk import surely_walking_until
from robot_ctrl.geometry.drawer_geometry import SLOTS, DrawerGeometry
from robot_ctrl.geometry.room import Approach, CabinetMove, CabinetPose, Room, check_move, plan_approach
from robot_ctrl.modes import BaseState, DrawerMethod, FilterMode, SpeedClass
from robot_ctrl.synthesis.synthesizer import GoalJump

MAX_DISTANCE = 6.0  # [m] farthest cabinet: a room's length
WALK_IN = 0.30  # [m] most the pelvis advances before the synthesis starts (the WPG's start and two steps: 0.26-0.28 m measured)


@dataclass(frozen=True)
class DrawerTask:
    """What a user asks of the drawer scenario: the cabinet's distance [m] ahead of the start
    pelvis, the slot holding the object, goal jumps, speed class, dynamic filter mode, control period
    [s], how the base is seen and which method drives the robot. ``run_drawer(robot, hw,
    DrawerTask(2.0, "front_left"), primitives)``; :meth:`check` refuses what cannot be run."""

    distance: float  # [m] closed front panel from the start pelvis, along the start heading
    slot: str = "front_left"
    jumps: tuple[GoalJump, ...] = ()
    dynfilter: FilterMode = FilterMode.FULL
    control_dt: float = 0.005  # [s]
    base_state: BaseState = BaseState.SIMULATED  # where the controller's base pose and velocity come from
    speed: SpeedClass = SpeedClass.NOMINAL  # how fast the synthesized sequence is played
    position_feedback: bool = True  # the commander's loops that bring the pelvis where the synthesis planned it
    method: DrawerMethod = DrawerMethod.OURS
    cabinet: CabinetPose | None = None  # in a room: where the cabinet stands (start frame); None: ``distance`` ahead
    room: Room = Room()
    moves: tuple[CabinetMove, ...] = ()  # in a room: goal jumps of the cabinet while the robot walks its approach

    @property
    def in_room(self) -> bool:
        return self.cabinet is not None

    def approach(self, comfort: float, geometry: DrawerGeometry) -> Approach | None:
        """The walk to the pose where the synthesized sequence takes over, in a room (None: the
        sequence starts where the robot stands). Raises ValueError naming ``cabinet`` when the
        cabinet's front cannot be reached."""
        if self.cabinet is None:
            return None
        c = self.cabinet
        try:
            return plan_approach(c, geometry.footprint(), self.room, geometry.body_radius,
                                 comfort + geometry.handover_walk)
        except ValueError as exc:
            raise ValueError(f"cabinet = {c}: {exc}") from exc

    def replanner(self, first: Approach, geometry: DrawerGeometry):
        """``replan(pose, xy)``: the approach from the start-frame point ``xy`` to the cabinet moved
        to ``pose``, inside the room where ``first`` placed it (ValueError: none)."""
        def replan(pose: CabinetPose, xy) -> Approach:
            return plan_approach(pose, geometry.footprint(), self.room, geometry.body_radius, first.handover_distance,
                                 start=xy, placed=first.room)
        return replan

    def move_approaches(self, comfort: float, geometry: DrawerGeometry) -> list[Approach]:
        """Each goal jump's approach from the start (``check_move``): what bounds the walk's time."""
        first = self.approach(comfort, geometry)
        return [check_move(first, m.pose, geometry.footprint(), geometry.body_radius) for m in self.moves]

    def check(self, comfort: float, shortest: float, geometry: DrawerGeometry | None = None) -> None:
        """Raise ValueError naming the setting and its allowed range (a cabinet straight ahead in a
        room: ``distance`` is its distance, checked as without a room)."""
        nearest = round(comfort + shortest + WALK_IN, 2)
        if self.slot not in SLOTS:
            raise ValueError(f"slot = {self.slot!r} is not one of {', '.join(SLOTS)}")
        geometry = geometry or DrawerGeometry()
        first = self.approach(comfort, geometry) if self.in_room else None
        if first is not None and first.walks:
            walk = geometry.handover_walk
            if comfort + walk < nearest:
                raise ValueError(f"drawer.handover_walk = {walk} m is shorter than the {nearest - comfort:.2f} m "
                                 "the synthesis needs before the comfort distance")
            if self.method is DrawerMethod.NAIVE:
                raise ValueError("method = naive walks straight in: its cabinet stands straight ahead, facing it")
            if self.jumps:
                raise ValueError(f"goal jump distance = {self.jumps[0].distance:g} m: a cabinet the robot walks "
                                 "round to moves to a pose (TIME:X,Y,YAW_DEG), not along its axis")
            self._check_moves(first, geometry)
            return
        if self.moves:
            raise ValueError(f"goal jump pose = {self.moves[0].pose}: a pose moves a cabinet the robot "
                             "walks round to (--cabinet); one straight ahead, facing it, jumps along its axis "
                             "(TIME:DISTANCE)")
        for name, d in [("distance", self.distance)] + [("goal jump distance", j.distance) for j in self.jumps]:
            if not nearest <= d <= MAX_DISTANCE:
                raise ValueError(f"{name} = {d} m is outside the allowed range [{nearest}, {MAX_DISTANCE}] m")
        before = self.distance
        for j in sorted(self.jumps, key=lambda j: j.time):
            if not 0 < j.time <= 30:
                raise ValueError(f"goal jump time = {j.time} s is outside the allowed range (0, 30] s")
            if not j.distance > before:
                raise ValueError(f"goal jump distance = {j.distance} m must be farther than the {before} m before it "
                                 "(the cabinet moves away, thesis Fig. 3.39; nearer would put it into the robot)")
            before = j.distance

    def _check_moves(self, first: Approach, geometry: DrawerGeometry) -> None:
        """One goal jump at most in a room, while the robot surely still walks its approach, to a pose
        it can walk to from where it may be (``check_move``)."""
        if len(self.moves) > 1:
            raise ValueError(f"goal jump pose = {self.moves[1].pose}: a cabinet in a room moves once "
                             f"({len(self.moves)} jumps)")
        latest = surely_walking_until(first)
        for move in self.moves:
            if not 0 < move.time <= latest:
                raise ValueError(f"goal jump time = {move.time:g} s is outside the allowed range (0, {latest:g}] s "
                                 "(while the robot surely still walks its approach)")
            try:
                check_move(first, move.pose, geometry.footprint(), geometry.body_radius)
            except ValueError as exc:
                raise ValueError(f"goal jump pose = {move.pose}: {exc}") from exc
