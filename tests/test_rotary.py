import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from accelrig.acquisition.url import DeviceURL
from accelrig.cli import main
from accelrig.errors import DataError, DeviceError
from accelrig.procedures.rotary.bench import EncoderLog, analyse_test, read_encoder_csv
from accelrig.procedures.rotary.campaign import load_campaign, report_markdown, run_campaign, write_report
from accelrig.procedures.rotary.procedure import RotaryProcedure
from accelrig.recording import load_recording, save_recording
from accelrig.sim.campaign import paper_sensor, write_sim_campaign
from accelrig.sim.device import simulate
from accelrig.sim.rigs.rotary import (
    RotaryRig,
    encoder_samples,
    true_sensitivity,
    write_encoder_csv,
)
from accelrig.sim.sensor import SimClock
from accelrig_drivers.sim import build_device

NOMINAL = 1660.0


def make_test(seed=0, seconds=5.0, frequency=5.0, amplitude=34.0, rate_error=0.0037, tangential="x", radial="y",
              ref=False):
    rng = np.random.default_rng(seed)
    sensor = paper_sensor(rng)
    clock = SimClock(NOMINAL, rate_error, 0.0)
    rig = RotaryRig(frequency=frequency, amplitude_deg=amplitude, tangential=tangential, radial=radial,
                    duration=seconds, ref=ref, phase=float(rng.uniform(-np.pi, np.pi)), ref_gain_error=0.001)
    rec = simulate(rig, sensor, clock, seconds=seconds, seed=seed, units="counts")
    truth = true_sensitivity(rec.meta["truth"])
    enc = EncoderLog(**encoder_samples(rig, seconds, 1000.0, ref_noise=0.02 if ref else 0.0, rng=rng))
    return rec, enc, truth, clock, rig


# ---------------------------------------------------------------- rig


def test_rig_reproduces_the_papers_accelerations():
    rig = RotaryRig(radius=0.170, frequency=5.0, amplitude_deg=34.0, phase=0.0)
    t = np.linspace(0, 1, 20001)
    f = rig.specific_force(t)
    # 34 degrees peak to peak at 5 Hz, r = 170 mm: 49 m/s^2 tangential, 15 m/s^2 peak centripetal
    assert np.max(np.abs(f[:, 0])) == pytest.approx(49.78, abs=0.01)
    assert np.max(f[:, 1]) == pytest.approx(14.77, abs=0.01)
    assert np.min(f[:, 1]) >= 0  # points to the axis: never negative
    assert np.allclose(f[:, 2], 9.80665)
    assert rig.centripetal_amplitude == pytest.approx(np.max(f[:, 1]) / 2, rel=1e-6)
    # paper eq. 3-4, known here only: r (2 pi f)^2 theta0 and r (2 pi f theta0)^2 / 2
    theta0, w = np.deg2rad(17.0), 2 * np.pi * 5.0
    assert rig.tangential_amplitude == pytest.approx(0.170 * w**2 * theta0, rel=1e-9)
    assert rig.centripetal_amplitude == pytest.approx(0.170 * (w * theta0) ** 2 / 2, rel=1e-9)
    ref = RotaryRig(ref=True, ref_radius=0.145, ref_gain_error=0.001, phase=0.7)
    t = np.linspace(0, 1, 1001)
    expected = 1.001 * 0.145 * -(w**2) * theta0 * np.cos(w * t + 0.7)
    assert np.allclose(ref.ref_reading(t), expected, rtol=0, atol=1e-6)


@pytest.mark.parametrize("tangential, radial, up", [("x", "y", "z"), ("y", "x", "-z"), ("-y", "z", "-x"), ("z", "x", "y")])
def test_a_mounting_is_a_rotation_so_the_third_axis_may_point_down(tangential, radial, up):
    """No rigid sensor has y tangential, x radial and z up: that frame would be a mirror image."""
    rig = RotaryRig(tangential=tangential, radial=radial, phase=0.3)
    assert rig.truth()["up_axis"] == up
    force = rig.specific_force(np.linspace(0, 1, 101))
    i_up, sign = "xyz".index(up[-1]), -1.0 if up.startswith("-") else 1.0
    assert np.allclose(force[:, i_up], sign * 9.80665, rtol=0, atol=1e-6)
    assert np.allclose(np.linalg.det(rig.orientation(np.zeros(1))), 1.0)


def test_rig_url_options_and_channels():
    device, _ = build_device(DeviceURL.parse("sim://rotary?ref=1&tangential=z&radial=x&frequency=8&amplitude_deg=13"
                                             "&rate=1660&range=8&seconds=2"))
    block = device.next_block(100, 0.0)
    assert set(block.channels) == {"theta", "ref"}
    assert device.truth()["rig"]["up_axis"] == "y"
    with pytest.raises(DeviceError, match="same axis"):
        build_device(DeviceURL.parse("sim://rotary?tangential=x&radial=x"))
    with pytest.raises(DeviceError, match="unknown option"):
        build_device(DeviceURL.parse("sim://rotary?radious=0.2"))


# ---------------------------------------------------------------- one test


@pytest.fixture(scope="module")
def sim_test():
    return make_test(seed=11, ref=True)


def test_fit_recovers_rate_and_sensitivities(sim_test):
    rec, enc, truth, clock, rig = sim_test
    res = analyse_test(rec, enc, "x", "y", NOMINAL)
    assert abs(res.sample_rate.value - clock.true_rate) < 4 * res.sample_rate.uncertainty
    assert res.sample_rate.uncertainty < 0.01  # Hz: far below the 1 Hz grid of the paper's scan
    for axis in ("x", "y"):
        s = res.sensitivity[axis]
        assert s.value == pytest.approx(truth[axis], rel=5e-4)
        # u holds the radius (0.3 %): a stated uncertainty, not the scatter
        assert s.uncertainty / s.value == pytest.approx(0.003, rel=0.05)
    assert res.sensitivity["x"].component == "tangential" and res.sensitivity["y"].component == "centripetal"
    assert res.filter_gain["at_f"] == pytest.approx(1.0, abs=1e-9)
    assert res.bland_altman["bias"] == pytest.approx(0.0, abs=0.01)
    assert res.bland_altman["proportional_slope"] == pytest.approx(0.001, abs=3e-4)  # the ref's gain error
    doc = res.to_json_dict()
    json.dumps(doc, default=float)
    assert set(doc["sensitivity"]["x"]) >= {"value", "uncertainty", "component"}
    common = res.to_calibration_result().to_json_dict()
    assert common["correction"] is None  # two gains and no offsets: no canonical correction is invented
    assert common["parameters"]["sensitivity_y"]["value"] == pytest.approx(res.sensitivity["y"].value)


def test_scan_is_the_papers_one_hertz_grid(sim_test):
    rec, enc, truth, clock, _ = sim_test
    res = analyse_test(rec, enc, "x", "y", NOMINAL, rate_method="scan")
    assert res.sample_rate.value == float(round(res.sample_rate.value))
    assert abs(res.sample_rate.value - clock.true_rate) <= 1.0
    # the 1 Hz grid (1 / sqrt 12) and at most one sample of the whole-period record
    assert 1 / np.sqrt(12) <= res.sample_rate.uncertainty <= np.hypot(1 / np.sqrt(12), NOMINAL / res.n_samples)
    assert res.sensitivity["x"].value == pytest.approx(truth["x"], rel=5e-4)


def test_theta_channel_instead_of_an_encoder_log(sim_test):
    rec, enc, truth, clock, _ = sim_test
    res = analyse_test(rec, None, "x", "y", NOMINAL, frequency=5.0)
    assert abs(res.sample_rate.value - clock.true_rate) < 0.01
    assert res.sensitivity["y"].value == pytest.approx(truth["y"], rel=5e-4)


def test_other_orientation_and_frequency():
    rec, enc, truth, clock, _ = make_test(seed=5, frequency=8.0, amplitude=13.0, tangential="z", radial="x",
                                          rate_error=-0.0025)
    res = analyse_test(rec, enc, "z", "x", NOMINAL)
    assert res.up_axis == "y"
    assert res.sensitivity["z"].value == pytest.approx(truth["z"], rel=5e-4)
    assert res.sensitivity["x"].value == pytest.approx(truth["x"], rel=1e-3)


def test_bad_inputs_say_what_is_wrong(sim_test):
    rec, enc, _, _, _ = sim_test
    late = EncoderLog(enc.t + 100.0, enc.theta)
    with pytest.raises(DataError, match="do not overlap"):
        analyse_test(rec, late, "x", "y", NOMINAL)
    with pytest.raises(DataError, match="8 Hz not found"):
        analyse_test(rec, enc, "x", "y", NOMINAL, frequency=8.0)
    with pytest.raises(DataError, match="axis roles contradict"):
        analyse_test(rec, enc, "y", "x", NOMINAL)
    with pytest.raises(DataError, match="axis roles contradict"):
        analyse_test(rec, enc, "z", "y", NOMINAL)
    with pytest.raises(DataError, match="same axis"):
        analyse_test(rec, enc, "x", "x", NOMINAL)
    other, *_ = make_test(seed=12, seconds=3.0, frequency=8.0, amplitude=13.0)
    with pytest.raises(DataError, match=r"5.000 Hz not found on the tangential axis x .* strongest line is at 7.9"):
        analyse_test(other, enc, "x", "y", NOMINAL)
    clipped = rec.slice(0, len(rec))
    clipped.acc = clipped.acc.copy()
    clipped.acc[10, 0] = 32767
    with pytest.raises(DataError, match="clipped"):
        analyse_test(clipped, enc, "x", "y", NOMINAL)


def test_encoder_csv_roundtrip_and_errors(tmp_path):
    rig = RotaryRig(duration=2.0)
    path = tmp_path / "enc.csv"
    write_encoder_csv(path, encoder_samples(rig, 2.0, 500.0))
    log = read_encoder_csv(path)
    assert log.t.size == 1000 and log.ref is None
    bad = tmp_path / "bad.csv"
    bad.write_text("t,angle\n0,0\n")
    with pytest.raises(DataError, match="lacks column"):
        read_encoder_csv(bad)


# ---------------------------------------------------------------- CLI


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "accelrig", *args], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("rotary")
    rec, enc, truth, clock, rig = make_test(seed=3, seconds=4.0)
    rec.t = np.arange(len(rec)) / NOMINAL
    rec.channels = {}
    save_recording(rec, d / "m.csv")
    write_encoder_csv(d / "e.csv", encoder_samples(rig, 4.0, 1000.0))
    return d, truth, clock


def test_cli_json(files, capsys):
    d, truth, clock = files
    code = main(["calibrate", "rotary", "--mems", str(d / "m.csv"), "--encoder", str(d / "e.csv"), "--radius", "0.170",
                 "--tangential", "x", "--radial", "y", "--nominal-rate", "1660", "--frequency", "5", "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)["details"]
    assert abs(doc["sample_rate_hz"]["value"] - clock.true_rate) < 0.01
    assert doc["sensitivity"]["x"]["component"] == "tangential"
    assert doc["sensitivity"]["y"]["value"] == pytest.approx(truth["y"], rel=1e-3)


def test_a_recording_from_accelrig_record_calibrates_without_units_and_a_bare_log_is_counts(files, tmp_path, capsys):
    """calibrate rotary read every file as counts unless told (newcomer 14 #5): a recording made by
    'accelrig record' (m/s^2 with its counts scale declared) was refused as "far too small for counts".  Now the
    file's declared units stand, and a log that declares nothing is counts, as a bench logger writes it."""
    rec = tmp_path / "rot.csv"
    assert main(["record", "sim://rotary?seed=3&pace=fast&rate=1000&seconds=4", "-o", str(rec)]) == 0
    assert '"units": "m/s^2"' in rec.read_text().splitlines()[0]
    capsys.readouterr()
    assert main(["calibrate", "rotary", "--mems", str(rec), "--radius", "0.170", "--tangential", "x", "--radial", "y",
                 "--nominal-rate", "1000", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)["details"]
    assert doc["sensitivity"]["x"]["component"] == "tangential"
    true = true_sensitivity(load_recording(rec).meta["truth"])
    assert doc["sensitivity"]["x"]["value"] == pytest.approx(true["x"], rel=5e-3)
    d, truth, _ = files
    bare = tmp_path / "bare.csv"
    bare.write_text("".join(line for line in (d / "m.csv").read_text().splitlines(keepends=True)
                            if not line.startswith("#")))
    assert main(["calibrate", "rotary", "--mems", str(bare), "--encoder", str(d / "e.csv"), "--radius", "0.170",
                 "--tangential", "x", "--radial", "y", "--nominal-rate", "1660", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)["details"]
    assert doc["sensitivity"]["y"]["value"] == pytest.approx(truth["y"], rel=1e-3)


def test_an_encoder_log_in_utc_meets_a_recording_that_carries_its_utc_start(files, tmp_path):
    """A BLE sensor recorded with 'accelrig record' (t from 0, its UTC start in the metadata) and the bench's
    encoder logged on the lab's clock in UTC epoch seconds: the two meet on UTC (newcomer 14 #4 was told they
    'do not overlap in time'); a recording without a UTC start says what is missing."""
    d, truth, _ = files
    origin = 1795587089.25
    enc = read_encoder_csv(d / "e.csv")
    write_encoder_csv(tmp_path / "utc.csv", {"t": enc.t + origin, "theta": enc.theta})
    mems = load_recording(d / "m.csv")
    relative = analyse_test(mems, enc, "x", "y", NOMINAL, 5.0)
    with pytest.raises(DataError, match="carries no UTC time"):
        analyse_test(mems, read_encoder_csv(tmp_path / "utc.csv"), "x", "y", NOMINAL, 5.0)
    mems.meta.update(time_base="utc", time_origin=origin)
    on_utc = analyse_test(mems, read_encoder_csv(tmp_path / "utc.csv"), "x", "y", NOMINAL, 5.0)
    for axis in ("x", "y"):
        assert on_utc.sensitivity[axis].value == pytest.approx(relative.sensitivity[axis].value, rel=1e-9)
        assert on_utc.sensitivity[axis].value == pytest.approx(truth[axis], rel=1e-3)


def test_cli_bad_input_is_one_line(files):
    d, _, _ = files
    r = run_cli("calibrate", "rotary", "--mems", str(d / "m.csv"), "--encoder", str(d / "e.csv"), "--radius", "0.170",
                "--tangential", "y", "--radial", "x", "--nominal-rate", "1660")
    assert r.returncode == 4
    assert r.stderr.count("\n") == 1 and "axis roles contradict" in r.stderr and "Traceback" not in r.stderr


def test_cli_missing_arguments(capsys):
    assert main(["calibrate", "rotary", "--mems", "m.csv", "--tangential", "x"]) == 4
    assert "needs --radius" in capsys.readouterr().err


# ---------------------------------------------------------------- campaign and session


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("campaign")
    truth = write_sim_campaign(d, n_sensors=2, repeats=2, seconds=2.5, seed=7, plan=((5.0, 34.0), (5.0, 16.0)),
                               orientations=(("x", "y"),))
    return truth, run_campaign(truth["yaml"])


def test_campaign_is_one_result_with_its_tables_in_details(campaign):
    _, result = campaign
    assert result.procedure == "rotary" and result.correction is None
    s1x = result.parameters["sensitivity_S1_x"]
    assert s1x.value == result.details["per_axis"]["S1"]["x"]["mean_sensitivity"]
    assert s1x.uncertainty == result.details["per_axis"]["S1"]["x"]["overall_uncertainty"]


def test_campaign_budget_groups_and_comparisons(campaign, tmp_path):
    truth, result = campaign
    report = result.details
    assert len(report["tests"]) == 8
    for sensor in ("S1", "S2"):
        for axis in ("x", "y"):
            e = report["per_axis"][sensor][axis]
            assert e["mean_sensitivity"] == pytest.approx(truth["sensors"][sensor][axis], rel=2e-3)
            budget = e["budget"]
            parts = [c["uncertainty"] for c in budget["contributions"]]
            assert [c["symbol"] for c in budget["contributions"]] == ["u_r", "u_l", "u_ref"]
            assert budget["combined_standard_uncertainty"] == pytest.approx(sum(parts))  # full correlation
            assert budget["expanded_uncertainty"] == pytest.approx(2 * sum(parts))
            assert e["linearity"]["r_squared"] > 0.9999
            # two amplitudes x two repeats: both setups found whatever order the tests come in
            assert e["repeatability"]["setups"] == 2 and e["repeatability"]["dof"] == 2
    assert set(report["per_sensor"]) == {"S1", "S2"}
    b = report["batch"]
    assert b["overall_relative_uncertainty"] >= max(s["overall_relative_uncertainty"] * 0.99
                                                    for s in report["per_sensor"].values()) / np.sqrt(2)
    assert report["normalized_error"][0]["sensors"] == ["S1", "S2"]
    assert "p_value" in report["anova"]["across_sensors"]
    assert len(report["bland_altman"]) == 8
    write_report(result, tmp_path / "r.md")
    write_report(result, tmp_path / "r.yaml")
    assert "Table 3" in (tmp_path / "r.md").read_text()
    assert yaml.safe_load((tmp_path / "r.yaml").read_text())["details"]["batch"]["mean_sensitivity"] == pytest.approx(
        b["mean_sensitivity"])
    with pytest.raises(DataError, match="suffix"):
        write_report(result, tmp_path / "r.txt")
    assert not (tmp_path / "r.txt").exists()


def test_axes_that_differ_are_said_beside_the_case_2_mean_that_stands_for_the_sensor(campaign):
    """Case 2 (paper 001, Table 3) is one value for the whole sensor, the mean of its axes with their spread in
    u; a newcomer read it as the sensitivity beside an ANOVA saying the axes differ (newcomer 14 #7)."""
    _, result = campaign
    differ = [s for s, a in result.details["anova"]["across_axes"].items() if a.get("means_differ")]
    assert differ   # the simulated sensors' axes differ by about 0.1-0.4 %, seen with repeats
    for sensor in differ:
        assert any(w.startswith(f"{sensor}: its axes' sensitivities differ (one-way ANOVA") and "case 1" in w
                   for w in result.warnings)
    assert f"| 2 | {differ[0]} (mean of its axes) |" in report_markdown(result)


def test_campaign_yaml_errors_name_the_field(campaign, tmp_path):
    truth, _ = campaign
    doc = yaml.safe_load(Path(truth["yaml"]).read_text())
    doc["tests"][0]["tangental"] = "x"
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(DataError, match=r"tests\[0\]\.tangental: unknown key"):
        load_campaign(bad)
    doc["tests"][0].pop("tangental")
    doc["correlation"] = 2
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(DataError, match=r"correlation: expected a number <= 1"):
        load_campaign(bad)


def test_cli_campaign_writes_report(campaign, tmp_path, capsys):
    truth, _ = campaign
    doc = yaml.safe_load(Path(truth["yaml"]).read_text())
    base = str(Path(truth["yaml"]).parent)
    doc["tests"] = [dict(t, mems=f"{base}/{t['mems']}", encoder=f"{base}/{t['encoder']}") for t in doc["tests"][:2]]
    small = tmp_path / "small.yaml"
    small.write_text(yaml.safe_dump(doc))
    out = tmp_path / "report.md"
    assert main(["calibrate", "rotary", "--campaign", str(small), "-o", str(out)]) == 0
    text = out.read_text()
    assert "Group results (Table 3)" in text
    # two tests of one amplitude: no line can be drawn, and the report says so instead of inventing u_l
    assert "linearity not evaluated" in text
    assert "span only 1.0" in text and "needs at least 1.5 : 1" in text   # how much spread a line needs
    assert main(["calibrate", "rotary", "--campaign", str(small), "--mems", "x.csv"]) == 4
    assert "drop --mems" in capsys.readouterr().err


def test_procedure_takes_timed_steps_from_the_stream_and_reports_the_campaign():
    values = {"tangential": "x", "radial": "y", "plan": "5:34,5:16", "repeats": 2, "seconds": 3.0, "radius": 0.170,
              "radius_uncertainty": 0.0005, "ref_radius": 0.145, "rate_method": "fit"}
    rng = np.random.default_rng(9)
    sensor = paper_sensor(rng)
    clock = SimClock(NOMINAL, 0.003, 0.0)
    with pytest.raises(DeviceError, match="theta"):
        RotaryProcedure.create(values, {"nominal_rate": NOMINAL, "channels": []})
    proc = None
    while proc is None or not proc.done:
        step = proc.next_step() if proc else None
        frequency, amplitude = (step.frequency, step.amplitude_deg) if step else (5.0, 34.0)
        # the bench runs a second longer than the step: the capture takes the step's seconds from the key press
        rig = RotaryRig(frequency=frequency, amplitude_deg=amplitude, duration=4.0, phase=float(rng.uniform(-3, 3)))
        rec = simulate(rig, sensor, clock, seconds=4.0, seed=int(rng.integers(1000)), units="counts")
        if proc is None:
            proc = RotaryProcedure.create(values, {"nominal_rate": NOMINAL, "channels": ["theta", "ref"],
                                                   "scale": rec.meta["scale"]})
            assert proc.instruction().startswith("Set the motor to 5 Hz, 34 degrees peak to peak")
            step = proc.next_step()
        assert proc.feed(rec.to_si().slice(0, 100)) == []  # not armed: the stream is only watched
        assert proc.act("capture")[0].kind == "instruction"
        si = rec.to_si().slice(100, len(rec))
        events = [e for a in range(0, len(si), 500) for e in proc.feed(si.slice(a, a + 500))]
        assert events[0].kind == "captured" and events[0].data["step"] == step.index
    assert [s.index for s, _ in proc.results] == [0, 1, 2, 3] and proc.next_step() is None
    report = proc.result()
    assert report.details["per_axis"]["sensor"]["x"]["linearity"]["n"] == 4
    assert proc.act("capture") == []


def test_a_step_the_bench_ran_at_another_angle_than_the_plan_is_not_kept():
    """The plan says 20 degrees, the bench swings 34 (newcomer 14 #6): the step was labelled 20deg and
    certified so; the encoder shows the swing, so the step is refused, saying both angles."""
    values = {"tangential": "x", "radial": "y", "plan": "5:20", "repeats": 1, "seconds": 2.0, "radius": 0.170,
              "radius_uncertainty": 0.0005, "ref_radius": 0.145, "rate_method": "fit"}
    rng = np.random.default_rng(4)
    rec = simulate(RotaryRig(frequency=5.0, amplitude_deg=34.0, duration=3.0), paper_sensor(rng),
                   SimClock(NOMINAL, 0.003, 0.0), seconds=3.0, seed=5, units="counts")
    proc = RotaryProcedure.create(values, {"nominal_rate": NOMINAL, "channels": ["theta"], "scale": rec.meta["scale"]})
    proc.act("capture")
    events = proc.feed(rec.to_si())
    assert [e.kind for e in events] == ["problem"] and proc.results == []
    assert "swinging 34.0 degrees peak to peak, the plan says 20" in events[0].message


def test_an_encoder_coarser_than_stated_gets_the_u_of_its_own_steps(sim_test):
    """The quantisation term uses the step the log shows when it is coarser than the stated 0.01 degree
    (held-out audit: a 0.1-degree encoder kept the stated step's u and covered the truth in 45 % of runs)."""
    from accelrig.procedures.rotary.bench import RotarySetup, encoder_step

    rec, enc, truth, _, _ = sim_test
    step = np.radians(0.1)
    coarse = EncoderLog(enc.t, np.rint(enc.theta / step) * step)
    assert encoder_step(coarse.theta) == pytest.approx(step, rel=1e-9)
    assert encoder_step(enc.theta) == pytest.approx(np.radians(0.01), rel=1e-6)   # the simulator's own
    assert encoder_step(enc.theta + 1e-7 * np.sin(np.arange(enc.t.size))) == 0.0   # not on a grid
    setup = RotarySetup(radius_uncertainty=1e-6, geometry_uncertainty=0.0)
    fine, rough = (analyse_test(rec, e, "x", "y", NOMINAL, setup=setup) for e in (enc, coarse))

    def u_q(res):
        (row,) = [c for c in res.reference["tangential"]["budget"]["contributions"] if c["symbol"] == "u_q"]
        return row

    assert u_q(rough)["note"] == "step 0.1 deg, read from the log (coarser than stated)"
    assert u_q(fine)["note"] == "step 0.01 deg"
    assert u_q(rough)["uncertainty"] == pytest.approx(10 * u_q(fine)["uncertainty"], rel=1e-3)   # theta0 refitted
    assert rough.sensitivity["x"].uncertainty > 2 * fine.sensitivity["x"].uncertainty


def test_a_swing_with_a_2nd_harmonic_is_no_sign_of_swapped_axes_and_its_crosstalk_is_in_u():
    """Held-out audit: a disk whose swing carries a 1 % 2nd harmonic puts 4 % of the tangential line at 2f on
    the tangential axis; at small angles that exceeds the centripetal line, and the test was refused as
    'axis x, not the radial axis y, carries the centripetal' (8 of 25 runs); through the sensor's cross-axis
    sensitivity it also moved the radial sensitivity by several u."""
    from accelrig.procedures.rotary.bench import AxisAmplitudes, check_axis_roles, sensitivities

    tangential = AxisAmplitudes(at_f=20000.0, at_f_uncertainty=1.0, at_2f=800.0, at_2f_uncertainty=1.0,
                                dc=0.0, dc_uncertainty=1.0)
    radial = AxisAmplitudes(at_f=100.0, at_f_uncertainty=1.0, at_2f=600.0, at_2f_uncertainty=1.0,
                            dc=600.0, dc_uncertainty=1.0)
    up = AxisAmplitudes(at_f=5.0, at_f_uncertainty=1.0, at_2f=2.0, at_2f_uncertainty=1.0, dc=4100.0,
                        dc_uncertainty=1.0)
    amplitudes = {"x": tangential, "y": radial, "z": up}
    with pytest.raises(DataError, match="axis x, not the 'radial' axis y"):
        check_axis_roles(amplitudes, 0, 1, 8.0)                         # a pure sine cannot put 800 there
    check_axis_roles(amplitudes, 0, 1, 8.0, motion_2f_share=0.04)       # the encoder shows the 2nd harmonic
    reference = {name: {"value": v, "relative_uncertainty": 1e-4} for name, v in
                 (("tangential", 47.0), ("centripetal", 1.41), ("dc", 1.41))}
    used, _ = sensitivities(amplitudes, reference, 0, 1)
    # coupling 100 / 20000 seen at f, times the 800 counts at 2f, phase unknown: / sqrt 2
    expected = 100 / 20000 * 800 / np.sqrt(2) / 600
    assert used["y"].crosstalk_uncertainty == pytest.approx(expected)
    assert used["y"].uncertainty == pytest.approx(used["y"].value * np.sqrt((1 / 600) ** 2 + 1e-8 + expected**2))
    assert used["x"].crosstalk_uncertainty == 0.0
    # without a 2f line on the tangential axis the term is negligible
    clean = {**amplitudes, "x": AxisAmplitudes(20000.0, 1.0, 3.0, 1.0, 0.0, 1.0)}
    quiet = sensitivities(clean, reference, 0, 1)[0]["y"]
    assert quiet.crosstalk_uncertainty < 0.02 * quiet.noise_uncertainty
