"""Which device suits which wizard, and the simulated rig each wizard offers when the device does not.

A wizard started on a device of the wrong kind (a simulated static rig for
the wheel, a device without an encoder for the rotary bench) says so and
offers the matching simulated rig with settings that finish quickly, or the
connect list with the devices that fit first.  What can be told about a
device: a simulated one (``sim://RIG``, ``i2c-sim://CHIP?rig=RIG``) names its
rig; any device lists its channels (``theta`` encoder angle, ``step`` marks).
A real device without channels could be on any rig: it is not refused.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from accelrig.acquisition.url import DeviceURL
from accelrig.errors import AccelrigError

SIM_CHIPS = ("mpu9250", "icm20948")   # the register-level emulators (i2c-sim://), flashable


@dataclass(frozen=True)
class RigNeeds:
    """What one wizard's rig is, and the simulated rig offered in its place."""

    sim_rig: str                 # the simulated rig that plays this procedure (sim://NAME)
    motion: str                  # what a device of the wrong kind lacks, for people
    demo_url: str                # a simulated rig with range, rate and length that finish
    demo_texts: dict[str, str] = field(default_factory=dict)   # the setup form for that rig
    demo_note: str = ""          # what the demo does, for people


NEEDS: dict[str, RigNeeds] = {
    "static": RigNeeds(
        "static", "still poses on six faces",
        "sim://static",
        {},
        "a sensor put on its six faces in turn, then one face of each axis again, then the opposite faces "
        "once more, then the first faces a third time, 4 s each (about 90 s)"),
    "wheel": RigNeeds(
        "wheel", "rotation (a wheel spun and left to coast)",
        "sim://wheel?range=4&pace=fast&seconds=45&rest=5&push=2",
        {"radius": "0.28"},
        "a wheel of 0.28 m radius held still 5 s, pushed by hand, then coasting for 45 s, played fast: "
        "what the wizard asks of a real wheel"),
    "slider-crank": RigNeeds(
        "slider-crank", "a slider-crank stand's motion (with or without step marks)",
        "sim://slider-crank?range=8&rate=2048&pace=fast&steps=3,6,9&truth=ideal",
        {"crank_radius": "0.00635", "rod_length": "0.0353", "speeds": "3,6,9"},
        "an ideal sensor on a 6.35 mm crank at 3, 6 and 9 Hz, ±8 g, played fast"),
    "rotary": RigNeeds(
        "rotary", "an encoder angle (a 'theta' channel) on an oscillating bench",
        "sim://rotary?range=8&rate=1000&seconds=3600",
        {"radius": "0.170", "tangential": "x", "radial": "y", "plan": "5:34", "repeats": "2", "seconds": "2"},
        "a bench at 5 Hz, 34 degrees, ±8 g, 1000 Hz: two repeats of 2 s (one amplitude: no linearity term)"),
}


# The static wizard's multi-position model needs >= 9 distinct orientations; sim://static plays the six faces.
ORIENTATIONS_DEMO_URL = "sim://static?orientations=12&pace=fast"
ORIENTATIONS_DEMO_NOTE = "12 still poses in orientations drawn over all rotations, 4 s each, played fast"


def plays_faces_only(url: str) -> bool:
    """A simulated static rig that plays the six faces (and repeats of them): six distinct orientations,
    fewer than the multi-position model needs."""
    if simulated_rig(url) != "static":
        return False
    try:
        return "orientations" not in DeviceURL.parse(url).params
    except AccelrigError:
        return False


def simulated_rig(url: str) -> str | None:
    """The rig a simulated device plays (None: a real device or a replay, which could be anything)."""
    try:
        parsed = DeviceURL.parse(url)
    except AccelrigError:
        return None
    if parsed.scheme == "sim":
        return parsed.target.strip("/")
    if parsed.scheme == "i2c-sim":
        return parsed.get_str("rig", "still")
    return None


def rig_problem(procedure, url: str, device: dict) -> str | None:
    """Why the device at ``url`` cannot serve ``procedure`` (a Procedure class), or None when it can."""
    needs = NEEDS.get(procedure.name)
    missing = [c for c in procedure.channels_needed if c not in device.get("channels", ())]
    rig = simulated_rig(url)
    if needs is not None and rig is not None and rig != needs.sim_rig:
        return f"{url} is a simulated {rig} rig: it lacks {needs.motion}, which the {procedure.title} needs"
    if missing:
        return f"{url} delivers no {', '.join(missing)} channel: the {procedure.title} needs {needs.motion if needs else 'it'}"
    return None


def fits(procedure_name: str, url: str) -> bool:
    """A found device that certainly suits the wizard (a simulated rig of its kind)."""
    needs = NEEDS.get(procedure_name)
    return needs is not None and simulated_rig(url) == needs.sim_rig


def suggested_urls(procedure_name: str | None) -> list[tuple[str, str]]:
    """(url, why) offered first in the connect list: the wizard's simulated rig, then the flashable
    emulated chips (on the wizard's rig where the I2C emulator can play it: it delivers no encoder or step
    channel; else on the static rig: calibrate, then flash)."""
    needs = NEEDS.get(procedure_name) if procedure_name else None
    out = []
    if needs is not None:
        out.append((needs.demo_url, f"simulated {needs.sim_rig} rig for this wizard: {needs.demo_note}"))
    rig = needs.sim_rig if needs is not None and needs.sim_rig in ("static", "wheel") else "static"
    out += [(f"i2c-sim://{chip}?rig={rig}", f"emulated {chip} on the I2C driver, {rig} rig (can be flashed)")
            for chip in SIM_CHIPS]
    return out
