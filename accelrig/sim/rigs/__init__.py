"""Simulated rigs by name, as used in sim://NAME URLs.

RIGS maps a name to its Rig class and imports a rig's module only when that
rig is asked for: sim://still loads neither the wheel nor scipy.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping

from accelrig.sim.rigs.base import Rig


class LazyRigs(Mapping[str, type[Rig]]):
    """name -> Rig class, from a table of "module:Class" resolved on first access."""

    def __init__(self, paths: dict[str, str]):
        self._paths = paths

    def __getitem__(self, name: str) -> type[Rig]:
        module, cls = self._paths[name].split(":")
        return getattr(importlib.import_module(module), cls)

    def __contains__(self, name: object) -> bool:  # Mapping's default would import the rig
        return name in self._paths

    def __iter__(self) -> Iterator[str]:
        return iter(self._paths)

    def __len__(self) -> int:
        return len(self._paths)


RIGS = LazyRigs({
    "still": "accelrig.sim.rigs.still:StillRig",
    "rotary": "accelrig.sim.rigs.rotary:RotaryRig",
    "wheel": "accelrig.sim.rigs.wheel:WheelRig",
    "slider-crank": "accelrig.sim.rigs.slider_crank:SliderCrankRig",
    "static": "accelrig.sim.rigs.static:StaticRig",
})
