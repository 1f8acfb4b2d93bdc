"""Simulated rigs by name, as used in sim://NAME URLs."""

from __future__ import annotations

from accelrig.sim.rigs.base import Rig
from accelrig.sim.rigs.rotary import RotaryRig
from accelrig.sim.rigs.slider_crank import SliderCrankRig
from accelrig.sim.rigs.static import StaticRig
from accelrig.sim.rigs.still import StillRig
from accelrig.sim.rigs.wheel import WheelRig

RIGS: dict[str, type[Rig]] = {
    "still": StillRig,
    "rotary": RotaryRig,
    "wheel": WheelRig,
    "slider-crank": SliderCrankRig,
    "static": StaticRig,
}
