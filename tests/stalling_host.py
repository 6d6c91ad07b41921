"""A controller that stalls while holding its interpreter lock: ``python stalling_host.py KIND
BUS_CONFIG STALL_S``. It opens the real backend KIND (``mit-can`` or ``dynamixel``) on the bus
config, holds the posture it finds at 30 % of the servo stiffness for 100 ticks (0.5 s at 200 Hz),
prints ``stalling``, then makes a C call that keeps the interpreter lock for STALL_S seconds
(``ctypes.PyDLL`` does not release it, unlike ``ctypes.CDLL``): no thread of this process runs
meanwhile, the safety layer's watchdog included. Then it resumes and closes."""

import ctypes
import sys
import time

import numpy as np

from robot_ctrl.backends import open_hardware
from robot_ctrl.hw.types import JointCommand
from robot_ctrl.robot.model import load_robot

kind, bus_config, stall = sys.argv[1], sys.argv[2], float(sys.argv[3])
robot = load_robot("talos")
with open_hardware(kind, robot, bus_config) as hw:
    hw.configure()
    hw.activate()
    held = hw.read().q.copy()
    zero = np.zeros(robot.nj)
    for _ in range(100):
        tick = time.monotonic()
        hw.write(JointCommand(q=held, dq=zero, kp=0.3 * robot.kp, kd=robot.kd, tau_ff=zero))
        hw.read()
        time.sleep(max(0.005 - (time.monotonic() - tick), 0.0))
    print("stalling", flush=True)
    ctypes.PyDLL(None).usleep(int(stall * 1e6))
    print("resumed", flush=True)
