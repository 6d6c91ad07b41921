"""A controller that stalls while holding its interpreter lock: ``python stalling_host.py KIND
BUS_CONFIG STALL_S``. It opens the real backend KIND (``mit-can`` or ``dynamixel``) on the bus
config, holds the posture it finds at 30 % of the servo stiffness at 100 Hz until 100 ticks in a row
passed without damping (1 s: the soft start done; a tick that overran trips the watchdog and starts
it again; the 10 ms period leaves room for the emulated buses' round trip between processes, about
7 ms over udp_multicast here), prints ``stalling``, then makes a C call that keeps the
interpreter lock for STALL_S seconds (``ctypes.PyDLL`` does not release it, unlike ``ctypes.CDLL``):
no thread of this process runs meanwhile, the safety layer's watchdog included. Then it resumes
and closes."""

import ctypes
import faulthandler
import sys
import time

import numpy as np

from robot_ctrl.backends import open_hardware
from robot_ctrl.hw.types import JointCommand
from robot_ctrl.robot.model import load_robot

kind, bus_config, stall = sys.argv[1], sys.argv[2], float(sys.argv[3])
faulthandler.dump_traceback_later(60, exit=True)
robot = load_robot("talos")
PERIOD = 0.01  # [s]
with open_hardware(kind, robot, bus_config, control_dt=PERIOD) as hw:
    hw.configure()
    hw.activate()
    held = hw.read().q.copy()
    zero = np.zeros(robot.nj)
    steady, damped, deadline = 0, 0, time.monotonic() + 30
    while steady < 100:  # ticks since the soft start began (again, after a damping episode)
        tick = time.monotonic()
        hw.write(JointCommand(q=held, dq=zero, kp=0.3 * robot.kp, kd=robot.kd, tau_ff=zero))
        hw.read()
        episodes = sum(hw.interventions[k] for k in ("watchdog", "stale_state"))
        steady, damped = (steady + 1, damped) if episodes == damped else (0, episodes)
        if time.monotonic() > deadline:
            sys.exit(f"no 100 ticks in a row without damping in 30 s ({damped} damping episodes)")
        time.sleep(max(PERIOD - (time.monotonic() - tick), 0.0))
    faulthandler.cancel_dump_traceback_later()
    print("stalling", flush=True)
    ctypes.PyDLL(None).usleep(int(stall * 1e6))
    print("resumed", flush=True)
