"""Certificates (accelrig report): every parameter with its U, figures that plot the result's own arrays,
sources read from disk, errors in one line.  The browser checks are in test_report_browser.py."""

from __future__ import annotations

import copy
import json
import math
import re

import numpy as np
import pytest

from accelrig.cli import main
from accelrig.report import certificate_html, from_result, load_source
from accelrig.report.figures import (
    noise_figure,
    residual_asd,
    rotary_figures,
    slider_crank_figure,
    static_figure,
    wheel_figure,
)
from accelrig.report.html import format_value, parameter_rows
from accelrig.result import to_json
from report_support import (
    DEVICE,
    EXAMPLES,
    certificate_text,
    example_script,
    first_difference,
    rotary_campaign_result,
    slider_crank_result,
    static_result,
    wheel_result,
)

pytest.importorskip("matplotlib")


@pytest.fixture(scope="module")
def static_run():
    return static_result()


@pytest.fixture(scope="module")
def wheel_run():
    return wheel_result()


@pytest.fixture(scope="module")
def slider_run():
    return slider_crank_result()


@pytest.fixture(scope="module")
def campaign_run(tmp_path_factory):
    return rotary_campaign_result(tmp_path_factory.mktemp("campaign"))


def text_of(html: str) -> str:
    return re.sub(r"<[^>]+>", " ", html)


def assert_every_parameter_with_its_u_and_U(result, html: str, k: float = 2.0) -> None:
    text = text_of(html)
    n = 0
    for name, est in result.parameters.items():
        values = est.value if isinstance(est.value, list) else [est.value]
        uncs = est.uncertainty if isinstance(est.uncertainty, list) else [est.uncertainty]
        for v, u in zip(values, uncs, strict=True):
            if est.unit == "rad":
                v, u = math.degrees(v), math.degrees(u)
            value_text, u_text = format_value(v, u)
            expanded = format_value(v, k * u)[1]
            row = re.search(rf"{re.escape(name)}(\[[xyz0-9]\])?\s+{re.escape(value_text)}\s+{re.escape(u_text)}"
                            rf"\s+{re.escape(expanded)}\s", text)
            assert row, f"{name} = {value_text} +- {u_text} (U {expanded}) not in the certificate"
            n += 1
    assert n >= len(result.parameters)
    if result.correction is not None:
        c = result.correction
        for i in range(3):
            value_text, u_text = format_value(c.bias[i], c.bias_uncertainty[i])
            expanded = format_value(c.bias[i], k * c.bias_uncertainty[i])[1]
            assert re.search(rf"b\[{'xyz'[i]}\]\s+{re.escape(value_text)}\s+{re.escape(u_text)}\s+"
                             rf"{re.escape(expanded)}", text)


def test_u_is_rounded_to_two_significant_digits_and_the_value_with_it():
    assert format_value(0.985581, 0.000112) == ("0.98558", "0.00011")
    assert format_value(45.0337, 0.0371) == ("45.034", "0.037")
    assert format_value(1234.5, 23.0) == ("1234", "23")


def test_tiny_numbers_share_a_power_of_ten_with_their_u():
    """Below 1e-3 the value and u are written with one exponent, u still to two significant digits."""
    assert format_value(0.000001315, 0.0000000123) == ("1.315e-6", "0.012e-6")
    assert format_value(0.000333313, 0.000000055) == ("3.33313e-4", "0.00055e-4")
    assert format_value(-2.5e-5, 3.04e-5) == ("-2.5e-5", "3.0e-5")          # the larger of the two sets it
    assert format_value(9.9996e-5, 2.1e-7) == ("1.0000e-4", "0.0021e-4")    # not a mantissa of 10.000
    assert format_value(0.0012, 0.000015) == ("0.001200", "0.000015")     # from 1e-3 up: plain decimals
    assert format_value(12345000.0, 23.0) == ("1.2345000e+7", "0.0000023e+7")


def test_static_certificate_holds_device_method_hash_every_parameter_and_warnings(static_run):
    result, rec = static_run
    src = from_result(result, rec, device=DEVICE)
    html = certificate_html(src, {"operator": "A. Tester", "temperature": "23.0 ± 1.0 °C", "certificate_number": "C-17"})
    assert_every_parameter_with_its_u_and_U(result, html)
    text = text_of(html)
    for needle in ("sim-0042", "mpu9250", "±4 g", "paper 000", "A. Tester", "23.0 ± 1.0 °C", "C-17",
                   rec.content_hash(), "k = 2", "95 %", "Lack of fit"):
        assert needle in text, needle
    for w in result.warnings:
        assert w in text


def test_static_figure_plots_the_pose_magnitudes_before_and_after_the_correction(static_run):
    result, _ = static_run
    fig = static_figure(from_result(result))
    means, c, g = result.arrays["pose_means"], result.correction, result.settings["g"]
    np.testing.assert_allclose(fig.series["before"], np.linalg.norm(means, axis=1) - g)
    np.testing.assert_allclose(fig.series["after"], np.linalg.norm(c.apply(means), axis=1) - g, atol=1e-12)
    used = [r["magnitude_residual"] for r in result.details["poses"] if "magnitude_residual" in r]
    np.testing.assert_allclose(fig.series["after"], used, atol=1e-12)
    assert fig.svg.startswith("<svg") and "|a| - g" in fig.svg


def test_wheel_certificate_and_figure(wheel_run):
    result, rec = wheel_run
    src = from_result(result, rec)
    html = certificate_html(src)
    assert_every_parameter_with_its_u_and_U(result, html)
    assert "Pedersini" in html and "cross-axis" in text_of(html)
    fig = wheel_figure(src)
    for key in ("speed_time", "speed_samples", "speed_fit", "speed_residuals", "t", "residuals", "angle_deg"):
        np.testing.assert_allclose(fig.series[key], result.arrays[key])
    assert "wheel angle (degrees)" in fig.svg and 0 <= fig.series["angle_deg"].min() < fig.series["angle_deg"].max() < 360
    # the spectrum of white residuals is flat near the noise density sigma * sqrt(2 / fs)
    sd = np.std(result.arrays["residuals"], axis=0)
    level = np.median(fig.series["spectrum"][1:], axis=0)
    np.testing.assert_allclose(level, sd * np.sqrt(2 / 200.0), rtol=0.25)


def test_residual_spectrum_finds_a_line_at_its_frequency():
    t = np.arange(20000) / 200.0
    res = np.random.default_rng(0).normal(0, 0.05, (t.size, 1)) + 0.05 * np.sin(2 * np.pi * 7.0 * t)[:, None]
    freq, asd = residual_asd(t, res)
    assert abs(freq[np.argmax(asd[1:, 0]) + 1] - 7.0) < 2 * (freq[1] - freq[0])


def test_slider_crank_certificate_has_the_verdict_and_the_figure_the_steps(slider_run):
    result, rec = slider_run
    src = from_result(result, rec)
    html = certificate_html(src)
    # U at the coverage factor the verification judged with (Student's t on the radius's effective dof)
    assert_every_parameter_with_its_u_and_U(result, html, k=result.details["radius_k"])
    assert f"k = {result.details['radius_k']:.2f}, Student" in text_of(html)
    assert "Verification certificate" in html
    assert "Slider-crank verification: " in text_of(html) and str(result.details["verdict"]) in text_of(html)
    assert result.details["verdict"] == "holds" and 'class="verdict-pass">holds' in html
    fig = slider_crank_figure(src)
    for key in ("frequency_hz", "amplitude", "model_amplitude", "model_lower", "model_upper", "radius_m",
                "radius_uncertainty_m"):
        np.testing.assert_allclose(fig.series[key], result.arrays[key])


def test_campaign_certificate_has_budgets_groups_en_and_figures(campaign_run):
    result, _ = campaign_run
    html = certificate_html(from_result(result))
    assert_every_parameter_with_its_u_and_U(result, html, k=result.details["coverage_factor"])
    text = text_of(html)
    assert "Uncertainty budget" in text and "repeatability" in text and "E_n" in text and "ANOVA" in text
    for sensor, axes in result.details["per_axis"].items():
        for axis, e in axes.items():
            # the group table and the budget print S, u and U by the one rule (format_value), as the parameter
            # table does: one quantity reads the same everywhere (they were printed .3f and .3g)
            s, u = format_value(e["mean_sensitivity"], e["overall_uncertainty"])
            expanded = format_value(e["mean_sensitivity"], e["expanded_uncertainty"])[1]
            assert re.search(rf"{sensor} axis {axis}\s+{re.escape(s)}\s+{re.escape(u)}\s+{re.escape(expanded)}\s", text)
            b = e["budget"]
            s_b, u_c = format_value(b["value"], b["combined_standard_uncertainty_absolute"])
            assert (f"S = {s_b} counts/(m/s²): u_c = {u_c}, "
                    f"U = {format_value(b['value'], b['expanded_uncertainty_absolute'])[1]} counts/(m/s²)") in text
    for t in result.details["tests"]:   # every test's sensitivity with its U
        for e in t["sensitivity"].values():
            value_text, u_text = format_value(e["value"], e["uncertainty"])
            assert re.search(rf"{re.escape(value_text)}\s+{re.escape(u_text)}\s+"
                             rf"{re.escape(format_value(e['value'], 2 * e['uncertainty'])[1])}", text)
    figs = {f.key: f for f in rotary_figures(from_result(result))}
    assert set(figs) == {"rotary-sensitivity", "rotary-linearity", "rotary-bland-altman"}
    tests = result.details["tests"]
    np.testing.assert_allclose(figs["rotary-sensitivity"].series["sensitivity"],
                               [s["value"] for t in tests for s in t["sensitivity"].values()])
    for sensor, axes in result.details["per_axis"].items():
        for axis, e in axes.items():
            np.testing.assert_allclose(figs["rotary-linearity"].series[f"{sensor}_{axis}_output"],
                                       e["linearity"]["output"])
            np.testing.assert_allclose(figs["rotary-linearity"].series[f"{sensor}_{axis}_residuals"],
                                       e["linearity"]["residuals"], atol=1e-9)
            # the band is the line's own slope and intercept sd: at x = 0 it is the intercept's
            band = figs["rotary-linearity"].series[f"{sensor}_{axis}_band"]
            assert band[0] == pytest.approx(2 * e["linearity"]["intercept_sd"], rel=1e-9)
    np.testing.assert_allclose(figs["rotary-bland-altman"].series["bias"],
                               [b["bias"] for b in result.details["bland_altman"]])


def test_cli_from_a_profile_a_saved_result_and_a_campaign(static_run, campaign_run, tmp_path, capsys):
    from accelrig.profiles import profile_from_result, save_profile

    result, rec = static_run
    profile = tmp_path / "p.yaml"
    save_profile(profile_from_result(result, rec), profile)
    out = tmp_path / "from-profile.html"
    assert main(["report", str(profile), "-o", str(out), "--operator", "B. Lab", "--customer", "C. Ltd",
                 "--customer-reference", "PO 4711/B"]) == 0
    html = out.read_text()
    assert_every_parameter_with_its_u_and_U(result, html)
    assert "B. Lab" in html and rec.content_hash() in html
    # the customer's reference (order number) is stated, under the customer
    assert html.index("C. Ltd") < html.index("Customer reference") < html.index("PO 4711/B")
    # an issued certificate is not replaced unasked (the operator's name would be gone)
    assert main(["report", str(profile), "-o", str(out)]) != 0
    assert "B. Lab" in out.read_text()
    assert main(["report", str(profile), "-o", str(out), "--force"]) == 0
    assert "B. Lab" not in out.read_text()
    # a profile keeps no arrays: the figure it cannot draw is named, not faked
    assert "Figure not shown" in html

    saved = tmp_path / "r.json"
    saved.write_text(to_json(result.to_json_dict()))
    assert main(["report", str(saved), "-o", str(tmp_path / "r.html"), "--no-figures"]) == 0
    assert "9. Figures" not in (tmp_path / "r.html").read_text()
    assert main(["report", str(saved), "-o", str(tmp_path / "r2.html")]) == 0
    assert "<svg" in (tmp_path / "r2.html").read_text()   # the per-pose table is enough for the |g| figure

    campaign, truth = campaign_run
    assert main(["calibrate", "rotary", "--campaign", str(truth["yaml"]), "-o", str(tmp_path / "c.yaml")]) == 0
    capsys.readouterr()
    src = load_source(tmp_path / "c.yaml")
    assert src.is_campaign and set(src.result["parameters"]) == set(campaign.parameters)


def test_cli_bad_sources_and_outputs_are_one_line(tmp_path, capsys):
    missing = tmp_path / "none.yaml"
    assert main(["report", str(missing), "-o", str(tmp_path / "x.html")]) != 0
    assert "no such file" in capsys.readouterr().err
    odd = tmp_path / "odd.json"
    odd.write_text(json.dumps({"hello": 1}))
    assert main(["report", str(odd), "-o", str(tmp_path / "x.html")]) != 0
    assert "neither a profile" in capsys.readouterr().err
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    assert main(["report", str(broken), "-o", str(tmp_path / "x.html")]) != 0
    assert "not valid JSON" in capsys.readouterr().err
    assert not (tmp_path / "x.html").exists()


def test_wrong_output_suffix_is_refused(static_run, tmp_path, capsys):
    result, _ = static_run
    saved = tmp_path / "r.json"
    saved.write_text(to_json(result.to_json_dict()))
    assert main(["report", str(saved), "-o", str(tmp_path / "x.docx")]) != 0
    assert "use .html or .pdf" in capsys.readouterr().err


def test_parameter_rows_show_angles_in_degrees(static_run):
    result, _ = static_run
    rows = {r[0]: r for r in parameter_rows(from_result(result), 2.0)}
    angle = next(n for n in result.parameters if result.parameters[n].unit == "rad")
    assert rows[angle][4] == "deg"


def test_noise_figure_plots_the_measured_allan_curve_and_the_certified_terms(static_run, tmp_path, capsys):
    from accelrig.profiles import load_profile, profile_from_result, save_profile
    from accelrig.recording import write_csv
    from accelrig.sim.device import simulate
    from accelrig.sim.rigs.still import StillRig
    from accelrig.sim.sensor import SensorModel, SimClock

    rec = simulate(StillRig(), SensorModel(noise_density=300e-6 * 9.80665), SimClock(200.0), seconds=60, seed=5)
    rec.meta["chip"] = "mpu9250"
    still = tmp_path / "still.csv"
    write_csv(rec, still)
    profile = tmp_path / "p.yaml"
    save_profile(profile_from_result(static_run[0], rec), profile)
    assert main(["noise", str(still), "--profile", str(profile)]) == 0
    capsys.readouterr()
    assert main(["noise", str(still), "--json"]) == 0
    noise_json = tmp_path / "noise.json"
    noise_json.write_text(capsys.readouterr().out)
    measured = json.loads(noise_json.read_text())

    # from the profile alone: the terms its figures imply, and the datasheet line of the chip
    src = load_source(profile)
    fig = noise_figure(src)
    stored = load_profile(profile).noise
    tau = fig.series["tau_s"]
    for axis in "xyz":
        np.testing.assert_allclose(fig.series[f"white_{axis}"],
                                   stored["axes"][axis]["density"]["value"] / np.sqrt(2 * tau))
    np.testing.assert_allclose(fig.series["datasheet"], 300e-6 * 9.80665 / np.sqrt(2 * tau))
    assert "adev_x" not in fig.series and "not kept in the profile" in fig.caption

    # with the curves: the measured Allan deviation is what is plotted
    out = tmp_path / "n.html"
    assert main(["report", str(profile), "--noise", str(noise_json), "-o", str(out)]) == 0
    assert "Noise (Allan deviation)" in out.read_text()
    src.noise = measured
    fig = noise_figure(src)
    np.testing.assert_allclose(fig.series["tau_s"], measured["arrays"]["tau"])
    for axis in "xyz":
        np.testing.assert_allclose(fig.series[f"adev_{axis}"], measured["arrays"][f"adev_{axis}"])

    # curves of another recording are refused: they would contradict the certified figures
    other = dict(measured, recording_hash="sha256:" + "0" * 64)
    (tmp_path / "other.json").write_text(json.dumps(other))
    assert main(["report", str(profile), "--noise", str(tmp_path / "other.json"), "-o", str(tmp_path / "o.html")]) != 0
    assert "is not the one of the noise figures" in capsys.readouterr().err


@pytest.mark.parametrize("procedure", ["static", "wheel"])
def test_a_profile_gets_its_figures_from_the_recording_it_names_and_only_that_one(procedure, static_run, wheel_run,
                                                                                tmp_path):
    from accelrig.procedures.static.procedure import calibrate_static
    from accelrig.procedures.wheel.procedure import calibrate_wheel
    from accelrig.profiles import profile_from_result, save_profile
    from accelrig.recording import load_recording, write_csv
    from accelrig.report.figures import figures_for

    rec = (static_run if procedure == "static" else wheel_run)[1]
    path = tmp_path / "rec.csv"
    write_csv(rec, path)
    rec = load_recording(path)
    result = calibrate_static(rec) if procedure == "static" else calibrate_wheel(rec, radius=0.28)
    profile = tmp_path / "p.yaml"
    save_profile(profile_from_result(result, rec), profile)

    figures, missing = figures_for(load_source(profile))
    assert missing == [] and len(figures) == 1
    key = "after" if procedure == "static" else "speed_residuals"
    expected = (np.linalg.norm(result.correction.apply(result.arrays["pose_means"]), axis=1) - 9.80665
                if procedure == "static" else result.arrays["speed_residuals"])
    np.testing.assert_allclose(figures[0].series[key], expected, atol=1e-9)

    # another recording under the same name: no figure, and the reason
    text = path.read_text().splitlines()
    text[-1] = ",".join(text[-1].split(",")[:-1] + ["9.0"])
    path.write_text("\n".join(text) + "\n")
    figures, missing = figures_for(load_source(profile))
    assert figures == [] and "hash differs" in missing[0]


def test_the_figures_of_a_profile_with_poses_left_out_leave_them_out_again(static_run, tmp_path):
    """calibrate static --skip-pose: re-running for the figures leaves the same poses out, so the certified
    correction is reproduced (without them the re-run would not match and the figures would be dropped)."""
    from accelrig.procedures.static.procedure import calibrate_static
    from accelrig.profiles import profile_from_result, save_profile
    from accelrig.recording import load_recording, write_csv
    from accelrig.report.figures import figures_for

    path = tmp_path / "rec.csv"
    write_csv(static_run[1], path)
    rec = load_recording(path)
    result = calibrate_static(rec, skip_poses=[2, 9])
    profile = tmp_path / "p.yaml"
    save_profile(profile_from_result(result, rec), profile)
    figures, missing = figures_for(load_source(profile))
    assert missing == [] and len(figures) == 1


def test_a_relative_recording_name_finds_the_calibrated_file_beside_the_profile(static_run, tmp_path, monkeypatch):
    """Calibrated in a folder as 'six.csv', reported from its parent, which holds another six.csv: the file
    whose hash is the profile's is used (the first found was, and the figure was refused)."""
    from accelrig.procedures.static.procedure import calibrate_static
    from accelrig.profiles import profile_from_result, save_profile
    from accelrig.recording import load_recording, write_csv
    from accelrig.report.figures import figures_for

    rec = static_run[1]
    (tmp_path / "lab").mkdir()
    write_csv(rec, tmp_path / "lab" / "six.csv")
    monkeypatch.chdir(tmp_path / "lab")
    rec = load_recording("six.csv")
    save_profile(profile_from_result(calibrate_static(rec), rec), tmp_path / "lab" / "p.yaml")
    text = (tmp_path / "lab" / "six.csv").read_text().splitlines()
    text[-1] = ",".join(text[-1].split(",")[:-1] + ["9.0"])
    (tmp_path / "six.csv").write_text("\n".join(text) + "\n")   # another recording of that name, one up
    monkeypatch.chdir(tmp_path)
    figures, missing = figures_for(load_source("lab/p.yaml"))
    assert missing == [] and len(figures) == 1


def test_pdf_without_a_browser_says_so_and_writes_nothing(static_run, tmp_path, monkeypatch, capsys):
    result, _ = static_run
    saved = tmp_path / "r.json"
    saved.write_text(to_json(result.to_json_dict()))
    monkeypatch.setattr("accelrig.report.certificate.find_browser", lambda: None)
    assert main(["report", str(saved), "-o", str(tmp_path / "r.pdf"), "--no-figures"]) != 0
    assert "needs Chromium" in capsys.readouterr().err
    monkeypatch.undo()
    monkeypatch.setenv("ACCELRIG_CHROMIUM", str(tmp_path / "no-such-browser"))
    assert main(["report", str(saved), "-o", str(tmp_path / "r.pdf"), "--no-figures"]) != 0
    assert "could not start the browser" in capsys.readouterr().err
    assert not (tmp_path / "r.pdf").exists()


def test_format_value_keeps_two_digits_when_u_rounds_into_the_next_decade_and_takes_numpy_floats():
    import numpy as np

    from accelrig.result import format_value

    assert format_value(1.0, 0.0999996) == ("1.00", "0.10")
    assert format_value(np.float32(1.23456), np.float32(0.0123)) == ("1.235", "0.012")


def test_the_example_certificates_are_what_the_code_renders_now(static_run, wheel_run, campaign_run):
    """docs/examples/ holds certificates made by make_certificates.py from these simulated results: their text
    (not the times, not the drawings) must be what the code renders now.  When this fails after an intended
    change, run `python docs/examples/make_certificates.py` and commit the files it writes."""
    make = example_script()
    pages = make.certificate_pages(static_run, wheel_run, campaign_run[0], figures=False)
    assert set(pages) == {"certificate-static.html", "certificate-wheel.html", "certificate-rotary-campaign.html"}
    for name, page in pages.items():
        stored, rendered = certificate_text((EXAMPLES / name).read_text(encoding="utf-8")), certificate_text(page)
        assert stored == rendered, (f"docs/examples/{name} is not what the code renders now (run python "
                                    f"docs/examples/make_certificates.py):\n{first_difference(stored, rendered)}")


def test_a_profile_of_a_recording_that_declares_its_source_finds_the_file(static_run, tmp_path, monkeypatch, capsys):
    """A recording whose header declares a "source" text (as the real imucal file does) left that text in the
    profile, not the path, and the certificate could not find the recording.  The profile now keeps the file it
    was read from; a profile that names only a text says what it needs, and --recording gives the file (checked
    by its sha256; another file is refused and nothing is written)."""
    import yaml

    from accelrig.procedures.static.procedure import calibrate_static
    from accelrig.profiles import profile_from_result, save_profile
    from accelrig.recording import load_recording, write_csv
    from accelrig.report.figures import figures_for

    rec = static_run[1]
    rec.meta = {**rec.meta, "source": "example_data/six faces by hand (MIT)"}
    write_csv(rec, tmp_path / "six.csv")
    monkeypatch.chdir(tmp_path)
    rec = load_recording("six.csv")
    save_profile(profile_from_result(calibrate_static(rec), rec), tmp_path / "p.yaml")
    assert yaml.safe_load((tmp_path / "p.yaml").read_text())["provenance"]["recording_source"] == "six.csv"
    figures, missing = figures_for(load_source("p.yaml"))
    assert missing == [] and len(figures) == 1

    # a profile written before: it names the declared text
    data = yaml.safe_load((tmp_path / "p.yaml").read_text())
    data["provenance"]["recording_source"] = "example_data/six faces by hand (MIT)"
    (tmp_path / "old.yaml").write_text(yaml.safe_dump(data))
    figures, missing = figures_for(load_source("old.yaml"))
    assert figures == [] and "was not at hand" in missing[0] and data["provenance"]["recording_hash"] in missing[0]
    assert main(["report", "old.yaml", "-o", "a.html"]) == 0
    assert "--recording FILE" in capsys.readouterr().err   # the way out, on stderr, not on the certificate
    assert "--recording" not in (tmp_path / "a.html").read_text()
    assert main(["report", "old.yaml", "--recording", "six.csv", "-o", "b.html"]) == 0
    assert "Figure not shown" not in (tmp_path / "b.html").read_text()
    text = (tmp_path / "six.csv").read_text().splitlines()
    text[-1] = ",".join(text[-1].split(",")[:-1] + ["9.0"])
    (tmp_path / "other.csv").write_text("\n".join(text) + "\n")
    capsys.readouterr()
    assert main(["report", "old.yaml", "--recording", "other.csv", "-o", "c.html"]) != 0
    assert "not the recording this profile was calibrated from" in capsys.readouterr().err
    assert not (tmp_path / "c.html").exists()


def test_a_certificate_states_findings_and_keeps_internals_in_its_appendix(static_run):
    """A customer's certificate: no option of the program and no advice to the operator (the standard gravity's
    source told them to pass --g, --latitude, --height), no run facts (fit_seconds, n_evaluations), and the
    settings in the appendix, after the results."""
    from accelrig.report.wording import as_finding

    result, rec = static_run
    result = copy.deepcopy(result)
    result.warnings.append("the poses disagree with the model beyond their noise: the uncertainty allows for it; "
                           "let the sensor settle at a steady temperature and calibrate again")
    text = text_of(certificate_html(from_result(result, rec, device=DEVICE), figures=False))
    assert not re.search(r"(?<![\w-])--[a-z]", text), re.search(r".{80}(?<![\w-])--[a-z].{40}", text)
    for internal in ("fit_seconds", "n_evaluations"):
        assert internal not in text
    assert "the poses disagree with the model beyond their noise: the uncertainty allows for it." in text
    assert "calibrate again" not in text
    assert text.index("Appendix") > text.index("Warnings") and text.index("still_threshold") > text.index("Appendix")
    assert "standard gravity, standing for anywhere on Earth" in text   # the finding stays

    # the wording rule on its own: findings kept, advice and options' asides dropped
    assert as_finding("gain_x is poorly determined (u = 0.01): the mounting hides it; mount the sensor tilted") == (
        "gain_x is poorly determined (u = 0.01): the mounting hides it")
    assert as_finding("the six-face model (--model six-face) allows for tilted poses.") == (
        "the six-face model allows for tilted poses.")
    assert as_finding("u(g) is small: the gains' u rests on it; unless g was surveyed, state u(g) itself (--g-u)") == (
        "u(g) is small: the gains' u rests on it")
    assert as_finding("Nelder-Mead stopped before converging: too many evaluations") == (
        "Nelder-Mead stopped before converging: too many evaluations")
    # a finding that starts like advice or mentions an option is kept whole, the option said in words
    # (reviewer: the first two lost their first clause, the third its "given with ...")
    assert as_finding("hold 3 lasted 1.2 s: its mean is noisy") == "hold 3 lasted 1.2 s: its mean is noisy"
    assert as_finding("the device was calibrated with --range-g 4 but recorded at 8 g: its gains are off by 2x") == (
        "the device was calibrated with the range-g setting 4 but recorded at 8 g: its gains are off by 2x")
    assert as_finding("the cross-axis prior is 0.02 (given with --cross-axis-sd)") == (
        "the cross-axis prior is 0.02 (given with the cross-axis-sd setting)")
    # advice after a condition and its comma (the static drift and pose texts; the drift one used to end in
    # "After the six faces put one face of each axis down again", which reached the certificate)
    assert as_finding("a drift would shift the offsets by up to 0.01 m/s^2; to check, put one face of each axis "
                      "down again after the six faces (the wizard asks for it)") == (
        "a drift would shift the offsets by up to 0.01 m/s^2")
    assert as_finding("not face down (31 degrees from +z): kept; for six faces, put one face flat") == (
        "not face down (31 degrees from +z): kept")
    assert as_finding("the run was short; after the six faces, hold one again") == "the run was short"


def test_the_campaign_markdown_prints_s_and_u_by_the_one_rule(campaign_run):
    """calibrate rotary --campaign's Markdown printed S and U with .3f, the certificate by format_value."""
    from accelrig.procedures.rotary.campaign import report_markdown

    result, _ = campaign_run
    text = report_markdown(result)
    for sensor, axes in result.details["per_axis"].items():
        for axis, e in axes.items():
            s = format_value(e["mean_sensitivity"], e["overall_uncertainty"])[0]
            expanded = format_value(e["mean_sensitivity"], e["expanded_uncertainty"])[1]
            assert re.search(rf"\| 1 \| {sensor} axis {axis} \| {re.escape(s)} \| [0-9.]+ \| {re.escape(expanded)} \|",
                             text)
            assert f"### {sensor} axis {axis}: S = {s} counts per m/s^2" in text


def test_the_certificate_number_in_the_page_footer_cannot_end_the_style_element():
    # --number is free text, and the footer's CSS string sits inside <style>
    from accelrig.report.html import page_css

    css = page_css('12</style><script>alert(1)</script> "x"\\')
    assert "<" not in css and css.count('"') == 4   # the label's own quotes escaped: one string, then " of "
