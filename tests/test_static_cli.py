"""accelrig calibrate static: JSON contract, text report, one-line errors, nothing written on failure."""

import json

import numpy as np
import pytest

from accelrig.cli import main
from accelrig.recording import Recording, write_csv
from accelrig.sim.device import simulate
from accelrig.sim.rigs.static import StaticRig
from accelrig.sim.sensor import SensorModel, SimClock


@pytest.fixture(scope="module")
def six_face_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "six.csv"
    rec = simulate(StaticRig(np.random.default_rng(1)), SensorModel.random(np.random.default_rng(2)),
                   SimClock(200.0), seed=3)
    write_csv(rec, path)
    return path, rec


def test_json_holds_the_contracted_fields(six_face_csv, capsys):
    path, rec = six_face_csv
    assert main(["calibrate", "static", str(path), "--model", "paper", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "vp" and out["model"] in ("paper", "affine")
    corr = out["correction"]
    assert np.array(corr["matrix"]).shape == (3, 3) and np.array(corr["matrix_uncertainty"]).shape == (3, 3)
    assert len(corr["bias"]) == 3 and len(corr["bias_uncertainty"]) == 3
    for est in out["parameters"].values():
        assert set(est) == {"value", "uncertainty", "unit"} and est["uncertainty"] > 0
    assert 0.01 < out["residual_rms"] < 0.1
    truth = SensorModel.random(np.random.default_rng(2)).correction()
    err = np.array(corr["bias"]) - truth.bias
    assert np.all(np.abs(err) < 5 * np.array(corr["bias_uncertainty"]))


def test_paper_method_and_model_in_one_run_and_text_report(six_face_csv, capsys):
    path, _ = six_face_csv
    assert main(["calibrate", "static", str(path), "--model", "paper", "--method", "paper", "--json"]) == 0
    nm = json.loads(capsys.readouterr().out)
    assert nm["method"] == "paper" and set(nm["parameters"]) >= {"angle_x", "gain_y", "offset_z"}
    assert nm["parameters"]["angle_x"]["unit"] == "rad"
    assert main(["calibrate", "static", str(path), "--model", "paper", "--method", "paper"]) == 0   # as the JSON
    text = capsys.readouterr().out
    assert "angle_x" in text and "deg" in text and "calibrated = C @ (raw - b)" in text
    # the correction rounded as every face rounds it (was "+1.002937(0.001581)": six digits whatever u)
    from accelrig.result import format_value

    corr = nm["correction"]
    value, u = format_value(corr["matrix"][0][0], corr["matrix_uncertainty"][0][0])
    assert f"  C  +{value}({u})" in text
    value, u = format_value(corr["bias"][2], corr["bias_uncertainty"][2])
    assert f"{'' if value.startswith('-') else '+'}{value}({u}) m/s^2" in text


def _fails(argv, capsys):
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code != 0
    assert err.count("\n") == 0 and err.startswith("accelrig: error:") and "Traceback" not in err
    return err


def test_missing_faces_name_them_and_write_nothing(tmp_path, capsys):
    rec = simulate(StaticRig(np.random.default_rng(4), order=("+z", "-z", "+x", "-x")),
                   SensorModel.random(np.random.default_rng(5)), SimClock(200.0), seed=6)
    path = tmp_path / "four.csv"
    write_csv(rec, path)
    out = tmp_path / "profile.yaml"
    err = _fails(["calibrate", "static", str(path), "-o", str(out)], capsys)
    assert "missing +y, -y" in err
    assert not out.exists()


def test_empty_and_non_numeric_files(tmp_path, capsys):
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    assert "empty" in _fails(["calibrate", "static", str(empty)], capsys)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,ax,ay,az\n0,1,2,x\n")
    assert "not a number" in _fails(["calibrate", "static", str(bad)], capsys)


def test_data_in_g_declared_as_m_s2_name_the_flag(six_face_csv, tmp_path, capsys):
    _, rec = six_face_csv
    path = tmp_path / "in_g.csv"
    write_csv(Recording(rec.t, rec.acc / 9.80665, "m/s^2", {}, {}), path)
    assert "--units g" in _fails(["calibrate", "static", str(path)], capsys)
    # and declared correctly it calibrates
    assert main(["calibrate", "static", str(path), "--units", "g", "--json"]) == 0


def test_counts_need_the_range(six_face_csv, tmp_path, capsys):
    _, rec = six_face_csv
    counts = np.rint(rec.acc / rec.meta["scale"])
    path = tmp_path / "counts.csv"
    write_csv(Recording(rec.t, counts, "counts", {}, {}), path)
    assert "--range-g" in _fails(["calibrate", "static", str(path)], capsys)
    assert main(["calibrate", "static", str(path), "--range-g", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert abs(out["correction"]["matrix"][0][0] - 1) < 0.05


def test_profile_written_with_the_correction_and_its_uncertainty(six_face_csv, tmp_path, capsys):
    from accelrig.profiles import load_profile

    path, _ = six_face_csv
    out = tmp_path / "device.yaml"
    assert main(["calibrate", "static", str(path), "-o", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    profile = load_profile(out)
    assert np.allclose(profile.correction.matrix, result["correction"]["matrix"])
    assert np.allclose(profile.correction.bias_uncertainty, result["correction"]["bias_uncertainty"])
    assert profile.data["calibration"]["procedure"] == "static"


def test_skip_pose_leaves_out_the_poses_named_in_one_or_several_flags(six_face_csv, capsys):
    path, _ = six_face_csv
    assert main(["calibrate", "static", str(path), "--skip-pose", "2,5", "--skip-pose", "7", "--json",
                 "--no-store"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [r["index"] for r in out["details"]["poses"] if r["fate"] == "left out"] == [2, 5, 7]
    assert out["settings"]["skip_poses"] == [2, 5, 7]
    for bad in ("0", "two"):
        with pytest.raises(SystemExit):
            main(["calibrate", "static", str(path), "--skip-pose", bad])
        assert "--skip-pose" in capsys.readouterr().err
