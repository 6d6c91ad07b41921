"""JointCommand and JointState in shared memory, for a backend that runs in another process.

Each lives in one float64 buffer with a fixed layout, so a tick's exchange is a few array copies
and no serialization. The state's layout has a slot for every array field of ``JointState`` (one
per foot for ``foot_wrench``) and a presence flag for each; a ``foot_wrench`` without sides comes
back as None. ``floor_contacts`` (names, of varying number) is not in the buffer: it travels as
the reply to the call that produced the state.
"""

from __future__ import annotations

import numpy as np

from robot_ctrl.geometry import SIDES
from robot_ctrl.hw.types import SCENE_CHANNELS, JointCommand, JointState


class _Shared:
    """A float64 array over a ``multiprocessing`` RawArray; passes to a child process (by fork,
    or pickled when the process is spawned) as a view of the same memory."""

    def __init__(self, nj: int, raw):
        self.nj = nj
        self.raw = raw
        self.array = np.frombuffer(raw, dtype=float)

    @classmethod
    def allocate(cls, nj: int, context):
        return cls(nj, context.RawArray("d", cls.size(nj)))

    def __reduce__(self):
        return type(self), (self.nj, self.raw)


class SharedCommand(_Shared):
    """Rows ``q, dq, kp, kd, tau_ff`` (5 × nj)."""

    @staticmethod
    def size(nj: int) -> int:
        return 5 * nj

    def put(self, command: JointCommand) -> None:
        rows = self.array.reshape(5, self.nj)
        rows[0], rows[1], rows[2], rows[3], rows[4] = command.q, command.dq, command.kp, command.kd, command.tau_ff

    def get(self) -> JointCommand:
        return JointCommand(*self.array.reshape(5, self.nj).copy())


def _state_slots(nj: int) -> dict[tuple[str, str | None], int]:
    """(field, foot side or None) → length, in buffer order, after the time."""
    arrays = {"q": nj, "dq": nj, "tau": nj, "base_pos": 3, "base_quat_xyzw": 4, "base_linvel": 3, "base_angvel": 3,
              "base_linacc": 3}
    return {**{(name, None): n for name, n in arrays.items()}, **{("foot_wrench", side): 6 for side in SIDES},
            ("tau_demand", None): nj, ("temperature", None): nj,
            ("scene", None): SCENE_CHANNELS}


class SharedState(_Shared):
    """``t``, one presence flag per slot, then the slots of :func:`_state_slots`."""

    def __init__(self, nj: int, raw):
        super().__init__(nj, raw)
        slots = _state_slots(nj)
        start = 1 + len(slots)
        self._slots = []  # (field, side, view)
        for (field, side), length in slots.items():
            self._slots.append((field, side, self.array[start:start + length]))
            start += length
        self._present = self.array[1:1 + len(slots)]

    @staticmethod
    def size(nj: int) -> int:
        slots = _state_slots(nj)
        return 1 + len(slots) + sum(slots.values())

    def put(self, state: JointState) -> None:
        """Store ``state`` but its ``floor_contacts``. Raises ValueError for a foot other than left/right."""
        wrench = state.foot_wrench or {}
        if not set(wrench) <= set(SIDES):
            raise ValueError(f"JointState.foot_wrench sides {sorted(wrench)} must be among {SIDES}")
        self.array[0] = state.t
        for i, (field, side, view) in enumerate(self._slots):
            value = getattr(state, field) if side is None else wrench.get(side)
            self._present[i] = value is not None
            if value is not None and field == "scene":  # a prop's readings, padded with NaN
                view[:len(value)], view[len(value):] = value, np.nan
            elif value is not None:
                view[:] = value

    def get(self, floor_contacts: tuple[str, ...] = ()) -> JointState:
        fields, wrench = {}, {}
        for (field, side, view), present in zip(self._slots, self._present.tolist()):
            value = view.copy() if present else None
            if side is None:
                fields[field] = value
            elif value is not None:
                wrench[side] = value
        return JointState(t=float(self.array[0]), foot_wrench=wrench or None, floor_contacts=floor_contacts,
                          **fields)
