"""Write the three example certificates (static, wheel, rotary campaign) and a batch report from the simulator.

    python docs/examples/make_certificates.py [OUT_DIR]     (default: docs/examples)

Run from the repository root with the 'report' extra installed.  The issue date and the recordings' start
times are fixed, so a rerun changes the files only when the numbers, the words or the layout change.  tests/test_report.py checks that the files here are what
the code renders now: after a change that alters them, run this script and commit what it writes.
"""

from __future__ import annotations

import copy
import sys
import tempfile
from datetime import UTC, datetime
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from accelrig.files import atomic_write  # noqa: E402
from accelrig.report import certificate_html, from_result  # noqa: E402
from accelrig.report.batch import batch_report_html, load_batch  # noqa: E402
from report_support import (  # noqa: E402
    DEVICE,
    rotary_campaign_result,
    static_result,
    wheel_result,
    write_batch_profiles,
)

ISSUED = datetime(2026, 1, 15, 9, 0, tzinfo=UTC)
RECORDED = "2026-01-15T08:00:00Z"   # when the simulated recordings "started" (the simulator takes the clock's)
CONDITIONS = {"customer": "Example Structural Monitoring Ltd.", "customer_reference": "order 4500-0815",
              "operator": "A. Tester", "location": "Lab 2",
              "temperature": "23.0 ± 1.0 °C", "humidity": "45 ± 10 %"}
CAMPAIGN_SOURCE = "simulated campaign (accelrig.sim.campaign.write_sim_campaign, seed 7)"


def recorded_at_fixed_time(recording):
    """The recording with RECORDED as its start time (a copy: the caller's is left as it was)."""
    recording = copy.copy(recording)
    recording.meta = {**recording.meta, "start_time": RECORDED}
    return recording


def certificate_pages(static_run, wheel_run, campaign, figures: bool = True) -> dict[str, str]:
    """File name -> the certificate page, from ``static_result()``, ``wheel_result()`` and
    ``rotary_campaign_result(...)[0]`` (report_support's defaults: the seeds these examples are made from)."""
    (static, rec), (wheel, wheel_rec) = static_run, wheel_run
    campaign = copy.copy(campaign)
    # the campaign file lived in a temporary directory: name what it was instead
    campaign.details = {**campaign.details, "source": CAMPAIGN_SOURCE}
    sources = {
        "certificate-static.html": (from_result(static, recorded_at_fixed_time(rec), device=DEVICE), "EX-001"),
        "certificate-wheel.html": (from_result(wheel, recorded_at_fixed_time(wheel_rec), device=DEVICE), "EX-002"),
        "certificate-rotary-campaign.html": (from_result(campaign), "EX-003"),
    }
    return {name: certificate_html(src, {**CONDITIONS, "certificate_number": number}, figures=figures,
                                   issued=ISSUED)
            for name, (src, number) in sources.items()}


def batch_page(directory, figures: bool = True) -> str:
    """The batch report of the profiles ``write_batch_profiles(directory)`` wrote."""
    batch = load_batch([str(directory)])
    for src in batch.sources:   # the profiles lived in a temporary directory: name them by file alone
        src.path = Path(src.path).name
    return batch_report_html(batch, {**CONDITIONS, "certificate_number": "EX-004"}, figures=figures,
                             issued=ISSUED)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        campaign, _ = rotary_campaign_result(Path(tmp))
    pages = certificate_pages(static_result(), wheel_result(), campaign)
    with tempfile.TemporaryDirectory() as tmp:
        write_batch_profiles(tmp, start_time=RECORDED)
        pages["report-batch.html"] = batch_page(tmp)
    for name, page in pages.items():
        atomic_write(out / name, lambda fh, page=page: fh.write(page), text=True)
        print(f"wrote {out / name} ({len(page) // 1024} KiB)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent)
