"""Emulated drives in a process of their own (``robot-ctrl hw emulate``), as real drives are, driven
by a controller in another process on the real backends (``--hw mit-can``, ``--hw dynamixel``):
when the controller dies (SIGKILL) or stalls holding its interpreter lock, every drive stops by
itself within its own timeout, as the emulator's status file shows. The emulated MIT drives are
Damiao drives (they disable themselves after ``drive_timeout_s``); a Dynamixel's Bus Watchdog
stops it where it is (torque on, the goal frozen)."""

import json
import os
import random
import select
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
import yaml

from robot_ctrl.buses.bus_config import HW_CONFIGS

pytestmark = pytest.mark.realtime  # wall-clock timing: run apart from the parallel tests

TESTS = Path(__file__).resolve().parent
DRIVE_TIMEOUT = {"mit-can": 0.1, "dynamixel": 0.1}  # [s] Damiao drive_timeout_s; the backend's Bus Watchdog
#: [s] the status is rewritten every 10 ms and a drive looks at its timeout every 10 ms or sooner
SLACK = 0.05


def emulated_config(kind: str, folder: Path) -> Path:
    """The shipped emulated bus config, on UDP ports (MIT-CAN) or a device path (Dynamixel) of this
    test's own, so that nothing else on the machine hears it."""
    name = "talos_mit_can_emulated" if kind == "mit-can" else "talos_dynamixel_emulated"
    data = yaml.safe_load((HW_CONFIGS / f"{name}.yaml").read_text())
    if kind == "mit-can":
        group = f"239.255.{random.randint(0, 255)}.{random.randint(1, 254)}"
        ports = random.sample(range(20000, 60000), len(data["buses"]))
        data["buses"] = {bus: dict(options, channel=group, port=port)
                         for (bus, options), port in zip(data["buses"].items(), ports)}
        # A tick's round trip over udp_multicast here (7 ms) outlasts the 5 ms period: replies come
        # a tick late and the backend doubts them (second answers to one request, late at its stale
        # checks), which would fault the host before the test kills or stalls it. These tests are
        # about the drives' own timeout, so the host holds on through doubted replies.
        data["max_missed_replies"], data["stale_check_every"] = 1000, 0
    else:
        data["port"]["device"] = str(folder / "dynamixel")
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@contextmanager
def emulator(kind: str, config: Path, status: Path):
    process = subprocess.Popen([sys.executable, "-m", "robot_ctrl.cli", "hw", "emulate", "--hw", kind, "--bus-config",
                                str(config), "--status", str(status)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True, cwd=config.parent)
    try:
        deadline = time.monotonic() + 120
        while not status.exists():
            assert process.poll() is None, process.stdout.read()
            assert time.monotonic() < deadline, "the emulator wrote no status"
            time.sleep(0.05)
        yield process
    finally:
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=30)


def read(status: Path) -> dict:
    return json.loads(status.read_text())


def stopped(kind: str, drive: dict) -> bool:
    """Disabled (MIT: limp) or, for a Dynamixel, stopped by its Bus Watchdog."""
    return not drive["enabled"] if kind == "mit-can" else drive["stopped"]


def watch_until(status: Path, done, timeout: float) -> list[dict]:
    """The statuses read until ``done(status)`` or ``timeout`` [s]; the last one is the first done."""
    seen, deadline = [], time.monotonic() + timeout
    while time.monotonic() < deadline:
        seen.append(read(status))
        if done(seen[-1]):
            return seen
        time.sleep(0.002)
    raise AssertionError(f"not done in {timeout} s: {json.dumps(seen[-1])[:400]}")


def standing(status: dict) -> bool:
    """Every drive enabled and following its commands, the legs stiff (the stand's soft start has
    begun: the lighter joints' gains may still round to 0 in a Dynamixel's gain register)."""
    drives = status["drives"]
    return all(d["enabled"] and not d["stopped"] for d in drives.values()) and all(
        d["kp"] > 0 for joint, d in drives.items() if joint.startswith("leg_"))


def check_each_drive_stopped_within_its_timeout(kind: str, statuses: list[dict]) -> None:
    """Each drive stopped by itself within its timeout of its last command (its command age when
    first seen stopped), none before it; the status kept being rewritten."""
    timeout = DRIVE_TIMEOUT[kind]
    for joint in statuses[0]["drives"]:
        seen_stopped = next(s["drives"][joint] for s in statuses if stopped(kind, s["drives"][joint]))
        assert timeout <= seen_stopped["command_age_s"] <= timeout + SLACK, (joint, seen_stopped)
        if kind == "mit-can":
            assert seen_stopped["kp"] == 0.0 and seen_stopped["kd"] == 0.0
    assert statuses[-1]["t"] > statuses[0]["t"]
    assert all(stopped(kind, d) for d in statuses[-1]["drives"].values())


@pytest.mark.parametrize("kind", ["mit-can", "dynamixel"])
def test_a_killed_controller_leaves_every_drive_stopped_within_its_timeout(kind, tmp_path):
    config, status = emulated_config(kind, tmp_path), tmp_path / "drives.json"
    with emulator(kind, config, status) as served:
        host = subprocess.Popen([sys.executable, "-m", "robot_ctrl.cli", "hw", "stand", "--hw", kind, "--bus-config",
                                 str(config), "--duration", "10"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True, cwd=tmp_path)
        try:
            assert standing(watch_until(status, standing, 120)[-1])
            assert host.poll() is None, host.stdout.read()  # mid-stand
        finally:
            host.send_signal(signal.SIGKILL)
            host.wait()
        statuses = watch_until(status, lambda s: all(stopped(kind, d) for d in s["drives"].values()), 2.0)
        check_each_drive_stopped_within_its_timeout(kind, statuses)
        assert served.poll() is None  # the drives outlive their host
    if kind == "dynamixel":
        assert not (tmp_path / "dynamixel").exists() and not (tmp_path / "dynamixel").is_symlink()


@pytest.mark.parametrize("kind", ["mit-can", "dynamixel"])
def test_a_controller_that_holds_its_interpreter_lock_cannot_hold_off_the_drives_own_timeout(kind, tmp_path):
    """The safety layer's watchdog thread cannot run while its interpreter is held (it would damp the
    drives 2 control periods after the last write): the drives' own timeout acts, in their process."""
    config, status = emulated_config(kind, tmp_path), tmp_path / "drives.json"
    with emulator(kind, config, status):
        with open(tmp_path / "host.err", "w") as err:
            host = subprocess.Popen([sys.executable, str(TESTS / "stalling_host.py"), kind, str(config), "0.5"],
                                    stdout=subprocess.PIPE, stderr=err, text=True, cwd=tmp_path,
                                    env=dict(os.environ, PYTHONPATH=str(TESTS.parent)))
        try:
            # (the host exits after 60 s short of it: its stderr then says where it hung)
            said = host.stdout.readline().strip() if select.select([host.stdout], [], [], 120)[0] else ""
            assert said == "stalling", f"the host did not reach its stall: {(tmp_path / 'host.err').read_text()[-3000:]}"
            statuses = watch_until(status, lambda s: all(stopped(kind, d) for d in s["drives"].values()), 0.45)
            assert host.poll() is None  # still stalled when every drive had stopped
        finally:
            try:
                host.wait(timeout=60)
            finally:
                host.kill()  # no-op once it has exited
        first = statuses[0]["drives"]
        assert all(d["enabled"] and not d["stopped"] for d in first.values()), first
        check_each_drive_stopped_within_its_timeout(kind, statuses)
        # Until each stopped, the joints held the controller's stiffness (its soft start was done): no
        # damping reached them from the layer, whose watchdog would have sent it 20 ms (2 of the host's
        # periods) after the last write.
        stiff = [joint for joint, d in first.items() if d["kp"] > 0]
        assert len(stiff) == len(first), first
        for s in statuses:
            assert all(s["drives"][j]["kp"] > 0 for j in stiff if not stopped(kind, s["drives"][j]) or kind == "dynamixel")


def test_hw_emulate_refuses_what_cannot_serve_another_process_in_one_line(tmp_path, capsys):
    from robot_ctrl.cli import main

    device = tmp_path / "dynamixel"
    config = emulated_config("dynamixel", tmp_path)
    device.write_text("")  # something already there
    for argv, message in ((["--hw", "mujoco"], "name the drives to emulate, mit-can or dynamixel"),
                          (["--hw", "mit-can"], "hw emulate needs --bus-config"),
                          (["--hw", "mit-can", "--bus-config", "talos_mit_can"], "reaches this process only"),
                          (["--hw", "mit-can", "--bus-config", str(config)], "a dynamixel bus config, and --hw mit-can"),
                          (["--hw", "dynamixel", "--bus-config", str(config)], f"{device} is already there"),
                          (["--hw", "dynamixel", "--bus-config", str(config), "--status", str(tmp_path)],
                           "is a folder: give a file name")):
        assert main(["hw", "emulate", *argv]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
    assert device.read_text() == ""  # left as it was
    assert main(["hw", "stand", "--status", str(tmp_path / "s.json")]) == 2
    assert "--status is for hw emulate" in capsys.readouterr().err
