"""Batch reports (accelrig report SOURCES.../DIR): simulated devices of known gain, one far off; the numbers
against the truth, E_n and the outlier rule as the document states them, the command on a directory."""

from __future__ import annotations

import re

import numpy as np
import pytest

from accelrig.cli import main
from accelrig.errors import DataError
from accelrig.estimation.stats import normalized_error
from accelrig.report.batch import (
    Entry,
    batch_report_html,
    build_batch,
    judge_group,
    load_batch,
    sensitivity_from_correction,
)
from accelrig.report.source import from_result
from report_support import (
    BATCH_GOOD,
    EXAMPLES,
    certificate_text,
    example_script,
    first_difference,
    rotary_campaign_result,
    static_result,
    write_batch_profiles,
)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Profiles of BATCH_GOOD + 1 simulated parts in one directory, the last one's x gain far off."""
    directory = tmp_path_factory.mktemp("fleet")
    return directory, write_batch_profiles(directory)


def test_sensitivity_from_the_correction_is_the_gain_and_its_u_is_the_methods():
    result, _, sensor = static_result(5, with_sensor=True)
    corr = result.correction.to_dict()
    sens, u = sensitivity_from_correction(corr)
    assert np.all(np.abs(sens - sensor.gain) < 4 * u)
    # the static method estimates the correction's scale factors itself (1 / sensitivity): the same numbers,
    # with about their u
    scales = [result.parameters[f"gain_{a}"] for a in "xyz"]
    np.testing.assert_allclose(sens, [1 / g.value for g in scales], rtol=1e-3)
    np.testing.assert_allclose(u, [g.uncertainty / g.value**2 for g in scales], rtol=0.25)
    # the derivative: in the linear regime (covariance / 10^4) the sd over draws of C is the propagated u
    rng = np.random.default_rng(0)
    c = np.asarray(corr["matrix"])
    small = dict(corr, covariance=(np.asarray(corr["covariance"]) * 1e-4).tolist())
    draws = rng.multivariate_normal(c.ravel(), np.asarray(small["covariance"])[:9, :9], 4000)
    norms = np.linalg.norm(np.linalg.inv(draws.reshape(-1, 3, 3)), axis=2)
    np.testing.assert_allclose(norms.std(axis=0), sensitivity_from_correction(small)[1], rtol=0.06)


def test_e_n_is_against_the_weighted_mean_of_the_others_and_t_against_their_spread():
    from scipy.stats import t as student_t

    values = [1.00, 1.01, 0.99, 1.00, 1.02, 1.30]
    us = [0.01, 0.02, 0.01, 0.01, 0.02, 0.01]
    group = judge_group([Entry(f"d{i}", "sensitivity", "x", "1", v, u, i) for i, (v, u) in
                         enumerate(zip(values, us, strict=True))], 2.0, None)
    w = 1 / np.array(us[:5]) ** 2
    ref = float(np.sum(w * values[:5]) / w.sum())
    assert group.rows[5].reference == pytest.approx(ref)
    assert group.rows[5].e_n == pytest.approx(normalized_error(1.30, 0.02, ref, 2 / np.sqrt(w.sum())))
    others = np.array(values[:5])
    assert group.rows[5].t == pytest.approx((1.30 - others.mean()) / (others.std(ddof=1) * np.sqrt(1 + 1 / 5)))
    assert group.t_critical == pytest.approx(student_t.ppf(1 - 0.05 / 12, 4))
    assert [r.outlier for r in group.rows] == [False] * 5 + [True]
    assert group.birge_ratio > 1 and "and |t| >" in group.rule
    # three devices and no reference: the batch's spread cannot be measured, so nobody is judged (E_n
    # against the two others flagged all three parts, sound ones for their genuine differences)
    small = judge_group([Entry(f"d{i}", "bias", "x", "m/s²", v, 0.01, i) for i, v in enumerate([0, 0.005, 0.2])],
                        2.0, None)
    assert all(r.t is None for r in small.rows) and not small.judged and "--reference" in small.rule
    assert not any(r.outlier for r in small.rows) and all(abs(r.e_n) > 1 for r in small.rows)   # shown, not judged
    # against a named reference, E_n alone decides, and the rule says so
    small = judge_group([Entry(f"d{i}", "bias", "x", "m/s²", v, 0.01, i) for i, v in enumerate([0, 0.005, 0.2])],
                        2.0, "d0")
    assert small.judged and "against the reference device" in small.rule and "t not evaluated" in small.rule
    assert [r.outlier for r in small.rows] == [False, False, True] and small.rows[0].e_n is None


def test_a_batch_of_normal_spread_is_rarely_flagged():
    """The rule's false-alarm rate: groups of 8 devices drawn from one normal population, tiny u (so E_n
    always exceeds 1): the share of groups with any device flagged is the stated 5 %."""
    rng = np.random.default_rng(1)
    trials = 1000
    flagged = 0
    for _ in range(trials):
        values = rng.normal(1.0, 0.01, 8)
        group = judge_group([Entry(f"d{i}", "sensitivity", "x", "1", v, 1e-5, i) for i, v in enumerate(values)],
                            2.0, None)
        flagged += any(r.outlier for r in group.rows)
    assert 0.03 < flagged / trials < 0.07


def test_the_batch_flags_the_part_that_is_off_and_nothing_else(fleet):
    directory, truth = fleet
    batch = load_batch([directory])
    assert sorted(batch.labels) == sorted(truth)
    sens_x = next(g for g in batch.groups if (g.quantity, g.axis) == ("sensitivity", "x"))
    for row in sens_x.rows:   # each device's value is its true gain, within its stated uncertainty
        assert abs(row.entry.value - truth[row.entry.device].gain[0]) < 4 * row.entry.u
    assert [(j.entry.device, j.entry.quantity, j.entry.axis) for j in batch.outliers] == [
        (f"dev-{BATCH_GOOD + 1}", "sensitivity", "x")]
    html = batch_report_html(batch)
    text = re.sub(r"<[^>]+>", " ", html)
    assert "Outlier rule:" in text and "|E_n| &gt; 1" in html and "t_crit" in text
    for identity in truth:
        assert identity in text
    # every device's U (k = 2) is in the document
    for row in sens_x.rows:
        from accelrig.report.html import format_value

        assert format_value(row.entry.value, 2 * row.entry.u)[1] in text
    sens_fig = next(f for f in __import__("accelrig.report.figures", fromlist=["batch_figures"]).batch_figures(batch)
                    if f.key.startswith("batch-sensitivity"))
    np.testing.assert_allclose(sens_fig.series["x_value"], [r.entry.value for r in sens_x.rows])
    assert sens_fig.series["x_outlier"].tolist() == [r.outlier for r in sens_x.rows]


def test_a_reference_device_is_what_every_other_is_compared_with(fleet):
    directory, _ = fleet
    batch = load_batch([directory], reference="dev-1")
    sens_x = next(g for g in batch.groups if (g.quantity, g.axis) == ("sensitivity", "x"))
    ref = next(r for r in sens_x.rows if r.entry.device == "dev-1")
    assert ref.e_n is None and ref.reference is None
    other = next(r for r in sens_x.rows if r.entry.device == "dev-2")
    assert other.reference == ref.entry.value
    with pytest.raises(DataError, match="no such device"):
        load_batch([directory], reference="dev-99")


def test_a_campaign_gives_one_device_per_sensor_in_counts(tmp_path):
    result, _ = rotary_campaign_result(tmp_path)
    batch = build_batch([from_result(result)])
    assert {g.unit for g in batch.groups} == {"counts/(m/s²)"}
    group = batch.groups[0]
    assert len(group.rows) == len(result.details["per_sensor"])
    for row in group.rows:
        sensor = row.entry.device.split(": ")[-1]
        assert row.entry.value == result.details["per_axis"][sensor][group.axis]["mean_sensitivity"]


def test_accelrig_report_on_a_directory_writes_one_document_and_lists_what_it_skipped(fleet, tmp_path, capsys):
    directory, _ = fleet
    (directory / "notes.yaml").write_text("what: the bench's notes\n")
    try:
        out = tmp_path / "batch.html"
        assert main(["report", str(directory), "-o", str(out), "--number", "B-1", "--customer-reference",
                     "order 77"]) == 0
        captured = capsys.readouterr()
        assert "Customer reference" in out.read_text(encoding="utf-8") and "order 77" in out.read_text(encoding="utf-8")
        assert f"1 outliers: dev-{BATCH_GOOD + 1} sensitivity x" in captured.out
        assert "notes.yaml" in captured.err
        page = out.read_text(encoding="utf-8")
        assert "Calibration batch report" in page and "Files not read" in page and "<svg" in page
        # two files given by name work the same; --noise has no meaning for a batch
        files = [str(directory / "dev-1.yaml"), str(directory / "dev-2.yaml")]
        assert main(["report", *files, "-o", str(tmp_path / "two.html"), "--no-figures"]) == 0
        # two devices and no reference: nobody is called an outlier, and both outputs say why
        assert "outliers not judged: 2 devices are too few" in capsys.readouterr().out
        page = (tmp_path / "two.html").read_text(encoding="utf-8")
        assert "OUTLIER" not in page and "not judged" in page and "Not judged (6 of 6" in page
        assert main(["report", *files, "-o", str(tmp_path / "x.html"), "--noise", "n.json"]) != 0
        assert "--noise belongs to one device" in capsys.readouterr().err
    finally:
        (directory / "notes.yaml").unlink()


def test_the_batch_report_prints_to_pdf_in_chromium(fleet, tmp_path):
    import shutil
    import subprocess

    from accelrig.report.certificate import find_browser

    if find_browser() is None or shutil.which("pdftoppm") is None:
        pytest.skip("chromium or pdftoppm is not installed (.ci/run installs them; test_report_browser insists)")
    directory, _ = fleet
    pdf = tmp_path / "batch.pdf"
    assert main(["report", str(directory), "-o", str(pdf)]) == 0
    assert pdf.read_bytes().startswith(b"%PDF")
    subprocess.run(["pdftoppm", "-r", "30", "-png", str(pdf), str(tmp_path / "page")], check=True, timeout=120)
    pages = sorted(tmp_path.glob("page*.png"))
    assert len(pages) >= 3 and all(p.stat().st_size > 1000 for p in pages)


def test_the_example_batch_report_is_what_the_code_renders_now(fleet):
    """docs/examples/report-batch.html is make_certificates.py's batch report of these profiles: its text (not
    the times, not the drawings) must be what the code renders now; if not, run that script."""
    directory, _ = fleet
    stored = certificate_text((EXAMPLES / "report-batch.html").read_text(encoding="utf-8"))
    rendered = certificate_text(example_script().batch_page(directory, figures=False))
    assert stored == rendered, ("docs/examples/report-batch.html is not what the code renders now (run python "
                                f"docs/examples/make_certificates.py):\n{first_difference(stored, rendered)}")
