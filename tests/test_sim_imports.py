"""The simulator is ground truth: it imports no estimator, and a rig loads only what it needs."""

import json
import subprocess
import sys

from accelrig.sim.rigs import RIGS
from accelrig.sim.rigs.base import Rig


def modules_after(code: str) -> set[str]:
    """The modules a fresh interpreter holds after running ``code``."""
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True).stdout
    return set(json.loads(out.splitlines()[-1]))


def test_nothing_under_accelrig_sim_imports_procedures_or_estimation():
    loaded = modules_after(
        "import pkgutil, importlib, accelrig.sim\n"
        "for m in pkgutil.walk_packages(accelrig.sim.__path__, 'accelrig.sim.'): importlib.import_module(m.name)")
    assert "accelrig.sim.rigs.wheel" in loaded and "accelrig.sim.chips.emulator" in loaded
    assert not {m for m in loaded if m.startswith(("accelrig.procedures", "accelrig.estimation"))}


def test_a_still_device_loads_no_other_rig_and_no_scipy():
    loaded = modules_after(
        "from accelrig.acquisition.url import DeviceURL\n"
        "from accelrig_drivers.sim import build_device\n"
        "from accelrig.sim.rigs import RIGS\n"
        "assert 'wheel' in RIGS and sorted(RIGS) == ['rotary', 'slider-crank', 'static', 'still', 'wheel']\n"
        "build_device(DeviceURL.parse('sim://still?pace=fast'))[0].next_block(10, 0.0)")
    assert "accelrig.sim.rigs.still" in loaded
    assert not {m for m in loaded if m.startswith(("accelrig.sim.rigs.wheel", "accelrig.sim.rigs.rotary",
                                                   "accelrig.sim.rigs.slider_crank", "accelrig.sim.rigs.static",
                                                   "scipy"))}


def test_the_registry_resolves_every_rig_by_name():
    assert all(issubclass(cls, Rig) and cls.name == name for name, cls in RIGS.items())
    assert RIGS.get("nonesuch") is None and "nonesuch" not in RIGS
