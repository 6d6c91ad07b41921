"""The compiled kernels are all loaded before the safety layer activates the servos: a run compiles
nothing once they are on (robot_ctrl/kernels.py)."""

import importlib
import json
import pkgutil
import subprocess
import sys

import pytest
from numba.core.registry import CPUDispatcher

import robot_ctrl
from robot_ctrl.kernels import registered

# A drawer run over the emulated MIT-CAN bus on the estimated base: every stage of the loop (the
# synthesis, the MPC, the IK, the estimator and its attitude filter, the safety layer) on the
# bus's decoded states. Each kernel's signatures are noted when the safety layer has loaded them;
# the script prints those that appeared later, compiled in the loop.
_RUN = """
import json, sys
import robot_ctrl.hw.safety as safety
from robot_ctrl.cli import main
from robot_ctrl.kernels import registered

loaded = {}
def load_kernels(*args):
    seconds = load_kernels.real(*args)
    loaded.update({d: set(d.signatures) for d in registered()})
    return seconds
load_kernels.real, safety.load_kernels = safety.load_kernels, load_kernels
status = main(["drawer", "--distance", "1.2", "--hw", "mit-can-emulated", "--base-state", "estimated",
               "--quiet", "--no-html", "--out", sys.argv[1]])
late = {d.py_func.__qualname__: [str(s) for s in set(d.signatures) - loaded.get(d, set())] for d in registered()}
print(json.dumps({"status": status, "activated": bool(loaded), "late": {k: v for k, v in late.items() if v}}))
"""


@pytest.mark.realtime  # a whole drawer run in its own interpreter, beside the parallel suite's
def test_a_run_compiles_no_kernel_after_the_servos_are_activated(tmp_path):
    out = subprocess.run([sys.executable, "-c", _RUN, str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["status"] == 0 and result["activated"]
    assert result["late"] == {}, f"compiled in the loop, with argument types not registered: {result['late']}"


def test_every_compiled_function_of_the_package_is_a_registered_kernel():
    for module in pkgutil.walk_packages(robot_ctrl.__path__, "robot_ctrl."):
        if ".cli" not in module.name:
            importlib.import_module(module.name)
    kernels = set(registered())
    compiled = {f"{name}.{attr}": obj for name, mod in list(sys.modules.items()) if name.startswith("robot_ctrl")
                for attr, obj in vars(mod).items() if isinstance(obj, CPUDispatcher) and obj.__module__ == name}
    assert len(compiled) >= 27
    assert [name for name, obj in compiled.items() if obj not in kernels] == []
