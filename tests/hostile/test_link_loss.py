"""Loud link loss: a recording that lost more than LOSS_WARN_SHARE of its samples says so on stderr and in
what it leaves behind (the recording's metadata, the calibration's warnings)."""

from __future__ import annotations

import json

from accelrig.recording import LOSS_WARN_SHARE, load_recording


def test_record_with_heavy_loss_says_so_on_stderr_and_in_the_file(cli, tmp_path):
    out = tmp_path / "lossy.csv"
    result = cli("record", "sim://still?pace=fast&drop=0.5&seed=4", "--samples", "3000", "-o", out)
    assert result.returncode == 0
    lines = result.stderr.splitlines()
    assert len(lines) == 2 and lines[0].startswith("accelrig: warning: the link lost ")
    assert lines[1].startswith("accelrig record: kept ") and " samples lost in " in lines[1]
    rec = load_recording(out)
    assert rec.meta["lost_share"] > 0.3 and rec.meta["lost_samples"] > 1000
    assert any("the link lost" in w for w in rec.meta["warnings"])


def test_light_loss_stays_quiet(cli, tmp_path):
    out = tmp_path / "ok.csv"
    result = cli("record", "sim://still?pace=fast&seed=4", "--samples", "3000", "-o", out)
    assert result.returncode == 0 and result.stderr.startswith("accelrig record: kept 3000 samples")
    assert result.stderr.count("\n") == 1   # the summary alone: no warning
    assert load_recording(out).meta["lost_share"] <= LOSS_WARN_SHARE


def test_a_calibration_from_a_lossy_recording_carries_the_warning(cli, tmp_path):
    out = tmp_path / "lossy.csv"
    assert cli("record", "sim://static?pace=fast&drop=0.1&seed=2", "-o", out).returncode == 0
    result = cli("calibrate", "static", out, "--json")
    assert result.returncode == 0, result.stderr
    assert result.stderr.startswith("accelrig: warning: the link lost")
    assert any("the link lost" in w for w in json.loads(result.stdout)["warnings"])


def test_a_verification_from_a_lossy_recording_carries_the_warning(cli, tmp_path):
    out = tmp_path / "crank.csv"
    assert cli("record", "sim://slider-crank?seed=1&pace=fast&rate=2048&range=8&steps=3&drop=0.3&block=128",
               "-o", out).returncode == 0
    result = cli("verify", "slider-crank", out, "--crank-radius", "0.00635", "--rod-length", "0.0353", "--json")
    assert result.returncode in (0, 1), result.stderr   # the verdict is not the point here
    assert result.stderr.startswith("accelrig: warning: the link lost")
    assert any("the link lost" in w for w in json.loads(result.stdout)["warnings"])


def test_a_rotary_test_from_a_lossy_recording_carries_the_warning_and_places_the_gaps(cli, tmp_path):
    out = tmp_path / "rotary.csv"
    assert cli("record", "sim://rotary?seed=3&pace=fast&rate=1660&range=8&seconds=12&drop=0.2&block=64",
               "--units", "counts", "-o", out).returncode == 0
    result = cli("calibrate", "rotary", "--mems", out, "--radius", "0.170", "--tangential", "x", "--radial", "y",
                 "--nominal-rate", "1660", "--json")
    assert result.returncode == 0, result.stderr
    assert result.stderr.startswith("accelrig: warning: the link lost")
    warnings = json.loads(result.stdout)["warnings"]
    assert any("the link lost" in w for w in warnings)
    # the gaps are placed on the sample grid (from the recorder's gap list), not closed up
    assert any("are missing in" in w and "gap list" in w for w in warnings)


def test_a_rotary_campaign_with_a_lossy_test_says_so_on_stderr_and_in_the_report(cli, tmp_path):
    lossy, clean = tmp_path / "lossy.csv", tmp_path / "clean.csv"
    for out, drop in ((lossy, "&drop=0.2"), (clean, "")):
        assert cli("record", f"sim://rotary?seed=3&pace=fast&rate=1660&range=8&seconds=8&block=64{drop}",
                   "--units", "counts", "-o", out).returncode == 0
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(
        "name: loss\nnominal_rate: 1660\nunits: counts\nradius: 0.170\ntests:\n"
        "  - {sensor: S1, mems: clean.csv, tangential: x, radial: y, label: clean}\n"
        "  - {sensor: S1, mems: lossy.csv, tangential: x, radial: y, label: lossy}\n")
    result = cli("calibrate", "rotary", "--campaign", campaign, "--json")
    assert result.returncode == 0, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.startswith("accelrig: warning:")]
    assert len(lines) == 1 and lines[0].startswith("accelrig: warning: test 2 (lossy): the link lost ")   # numbered from 1
    tests = json.loads(result.stdout)["details"]["tests"]
    assert any("the link lost" in w for w in tests[1]["warnings"])
    assert not any("the link lost" in w for w in tests[0]["warnings"])
