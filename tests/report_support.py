"""Simulated results of all four procedures for the certificate tests and the example script."""

from __future__ import annotations

import numpy as np

from accelrig.acquisition.url import DeviceURL
from accelrig.sim.device import simulate
from accelrig.sim.rigs.slider_crank import SliderCrankRig
from accelrig.sim.rigs.static import StaticRig
from accelrig.sim.rigs.wheel import WheelRig
from accelrig.sim.sensor import SensorModel, SimClock

DEVICE = {"identity": "sim-0042", "chip": "mpu9250", "driver": "sim", "range_g": 4.0, "rate": 200.0}


def static_result(seed: int = 3):
    from accelrig.procedures.static.procedure import calibrate_static

    rig = StaticRig.from_url(DeviceURL.parse("sim://static"), np.random.default_rng(seed))
    sensor = SensorModel.random(np.random.default_rng(seed + 100))
    rec = simulate(rig, sensor, SimClock(200.0), seed=seed)
    return calibrate_static(rec), rec


def wheel_result(seed: int = 11, seconds: float = 40.0):
    from accelrig.procedures.wheel.procedure import calibrate_wheel

    rig = WheelRig(duration=seconds)
    sensor = SensorModel(range_g=4.0, noise_density=SensorModel.noise_density_for_sd(0.08, 200.0))
    rec = simulate(rig, sensor, SimClock(200.0), seconds=seconds, seed=seed)
    return calibrate_wheel(rec, radius=rig.radius), rec


def slider_crank_result(seed: int = 1):
    from accelrig.procedures.slider_crank.procedure import verify_slider_crank

    rig = SliderCrankRig(steps=[2.5, 5.0, 8.0, 10.0], axis="1,0.1,0")
    sensor = SensorModel(range_g=8.0, noise_density=SensorModel.noise_density_for_sd(0.08, 2048.0))
    rec = simulate(rig, sensor, SimClock(2048.0, 0.003, 20e-6), seed=seed)
    return verify_slider_crank([("sim", rec)], 0.00635, 0.0353, clearance=0.0002), rec


def rotary_campaign_result(directory, seed: int = 7):
    from accelrig.procedures.rotary.campaign import run_campaign
    from accelrig.sim.campaign import write_sim_campaign

    truth = write_sim_campaign(directory, n_sensors=2, repeats=2, seconds=2.5, seed=seed,
                               plan=((5.0, 34.0), (5.0, 16.0)), orientations=(("x", "y"),))
    return run_campaign(truth["yaml"]), truth
