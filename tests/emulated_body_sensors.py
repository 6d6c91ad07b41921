"""A body-sensor driver (``body_sensors: emulated_body_sensors:open_sensors`` in a bus config) for
tests that drive the emulated MIT-CAN bus as if its servos were real (``--hw mit-can``): the IMU
and foot force/torque readings of the emulator's simulated robot, without what no sensor measures
(the base's position and velocity, the floor contacts of other bodies, the scene), timestamped on
``CLOCK`` as a real driver's are on the wall clock. The test sets ``EMULATOR`` (and ``CLOCK``)."""

import dataclasses
import time

EMULATOR = None
CLOCK = time.monotonic


def open_sensors(robot, config):
    opened = CLOCK()

    def read():
        state = EMULATOR.body_state()
        return dataclasses.replace(state, t=CLOCK() - opened, base_pos=None, base_linvel=None, floor_contacts=(),
                                   scene=None)
    return read


def open_missing(robot, config):
    """A driver whose device is not there."""
    raise OSError("no such device: /dev/imu0")
