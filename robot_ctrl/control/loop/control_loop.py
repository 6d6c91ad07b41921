"""ControlLoop: one tick for every scenario, for one robot or several sharing a world.

A tick at time ``t_k = k dt``::

    commands = [controller.step(state)]      the measured state enters here, and only here
    hardware.write(command)                  the robot starts moving (a RobotProcess returns at once)
    recorder.on_command(tick)                log the tick: its plan against the state it used
    commander.begin_tick(t_k+1)              commanders see the group before the next tick's plan
    controller.prepare()                     the next tick's state-independent work, while the robot moves
    pacer.wait()                             real hardware only: sleep to the next tick's deadline
    states = [hardware.read()]               waits for the robot's control period to end
    recorder.on_state(tick)                  metrics of what the robot did
    stop.reason(tick)                        the first stop condition that holds ends the run

A simulated robot waits for its controller, so the loop runs as fast as it computes; a real one
does not, and a :class:`~robot_ctrl.control.loop.pacer.Pacer` keeps the ticks on absolute deadlines
(the state is read at the deadline, the command follows it by the controller's compute time).
A paced run freezes the objects that exist when it starts out of Python's garbage collector
(``gc.freeze``): a full collection over a loaded robot's modules and models takes tens of
milliseconds, several control periods, and would come at a moment nobody chose; what the run itself
allocates is still collected.
The controllers compute while their robots move, as on a real robot (ros2_control's split:
hardware components read and write, controllers step, the loop owns the timing). Commanders steer a
controller only through its command API (``set_velocity``, ``stop_at``, ...), at the controller's
sample hook or in ``begin_tick``; recorders and stop conditions only observe.
"""

from __future__ import annotations

import gc
import time
from dataclasses import dataclass
from typing import Protocol, Sequence

from robot_ctrl.control.loop.pacer import Pacer
from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.types import JointCommand, JointState


class Controller(Protocol):
    def prepare(self) -> None:
        """The part of the next ``step`` that needs no measured state."""

    def step(self, state: JointState) -> JointCommand:
        """The command for this tick from the measured ``state``."""

    def close(self) -> None:
        """Release what the controller holds outside this process."""


@dataclass(frozen=True)
class Tick:
    """What the loop hands its recorders and stop conditions. ``states``: in ``on_command``, the
    states the commands were computed from; in ``on_state`` and ``reason``, the states just read
    (time ``t + dt``)."""

    k: int
    t: float  # [s] time of the tick's command
    states: Sequence[JointState]
    commands: Sequence[JointCommand]


class Recorder(Protocol):
    def on_command(self, tick: Tick) -> None: ...

    def on_state(self, tick: Tick) -> None: ...


class Commander(Protocol):
    def begin_tick(self, t: float) -> None:
        """Before the controllers prepare the tick at time ``t`` [s]."""


class StopCondition(Protocol):
    def reason(self, tick: Tick) -> str | None:
        """Why the run ends after this tick, or None."""


@dataclass(frozen=True)
class LoopResult:
    """What :meth:`ControlLoop.run` returns: how many ticks ran, why the loop stopped, the last
    states read, the loop's wall-clock time [s] and its control period [s]."""

    ticks: int
    stop_reason: str
    states: list[JointState]  # the last states read
    wall_s: float  # [s] wall-clock time of the loop
    dt: float  # [s] control period of the loop

    @property
    def rtf(self) -> float:
        """Simulated (or robot) seconds per wall-clock second."""
        return self.states[0].t / self.wall_s if self.wall_s > 0 else float("inf")


class ControlLoop:
    """Runs controllers on hardware, one tick every ``dt`` seconds (read → step → write →
    prepare, module docstring), with commanders, recorders and stop conditions, until a stop
    condition gives a reason. One controller per hardware adapter; several robots share the tick.
    ``ControlLoop([hw], [controller], 0.005, stops=[TimeLimit(10.0)]).run([hw.read()])``."""

    def __init__(self, hardware: Sequence[HardwareAdapter], controllers: Sequence[Controller], dt: float, *,
                 commanders: Sequence[Commander] = (), recorders: Sequence[Recorder] = (),
                 stops: Sequence[StopCondition] = (), pacer: Pacer | None = None):
        if len(hardware) != len(controllers) or not hardware:
            raise ValueError("ControlLoop needs one controller per hardware adapter (at least one)")
        if not stops:
            raise ValueError("ControlLoop needs at least one stop condition (a time limit)")
        self.hardware, self.controllers, self.dt = list(hardware), list(controllers), dt
        self.commanders, self.recorders, self.stops = list(commanders), list(recorders), list(stops)
        self.pacer = pacer

    def run(self, states: Sequence[JointState]) -> LoopResult:
        """Run from the ``states`` just read until a stop condition holds; the controllers are
        closed on the way out, the hardware is left to its owner."""
        states = list(states)
        for commander in self.commanders:
            commander.begin_tick(0.0)
        wall0 = time.perf_counter()
        k = 0
        if self.pacer is not None:
            gc.freeze()
        try:
            while True:
                t = k * self.dt
                commands = [c.step(s) for c, s in zip(self.controllers, states)]
                for hw, command in zip(self.hardware, commands):
                    hw.write(command)
                tick = Tick(k, t, states, commands)
                for recorder in self.recorders:
                    recorder.on_command(tick)
                for commander in self.commanders:
                    commander.begin_tick(t + self.dt)
                for controller in self.controllers:
                    controller.prepare()
                if self.pacer is not None:
                    self.pacer.wait()
                states = [hw.read() for hw in self.hardware]
                tick = Tick(k, t, states, commands)
                for recorder in self.recorders:
                    recorder.on_state(tick)
                reason = next((r for r in (s.reason(tick) for s in self.stops) if r is not None), None)
                if reason is not None:
                    return LoopResult(k + 1, reason, states, time.perf_counter() - wall0, self.dt)
                k += 1
        finally:
            if self.pacer is not None:
                gc.unfreeze()
            for controller in self.controllers:
                controller.close()
