"""Write the three example certificates (static, wheel, rotary campaign) and a batch report from the simulator.

    python docs/examples/make_certificates.py [OUT_DIR]     (default: docs/examples)

Run from the repository root with the 'report' extra installed.  The issue date is fixed so a rerun
changes the files only when the numbers or the layout change.
"""

from __future__ import annotations

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
CONDITIONS = {"customer": "Example Structural Monitoring Ltd.", "operator": "A. Tester", "location": "Lab 2",
              "temperature": "23.0 ± 1.0 °C", "humidity": "45 ± 10 %"}


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    static, rec = static_result()
    wheel, wheel_rec = wheel_result()
    with tempfile.TemporaryDirectory() as tmp:
        campaign, _ = rotary_campaign_result(Path(tmp))
    # the campaign file lived in a temporary directory: name what it was instead
    campaign.details["source"] = "simulated campaign (accelrig.sim.campaign.write_sim_campaign, seed 7)"
    pages = {
        "certificate-static.html": (from_result(static, rec, device=DEVICE), "EX-001"),
        "certificate-wheel.html": (from_result(wheel, wheel_rec, device=DEVICE), "EX-002"),
        "certificate-rotary-campaign.html": (from_result(campaign), "EX-003"),
    }
    for name, (src, number) in pages.items():
        page = certificate_html(src, {**CONDITIONS, "certificate_number": number}, issued=ISSUED)
        atomic_write(out / name, lambda fh, page=page: fh.write(page), text=True)
        print(f"wrote {out / name} ({len(page) // 1024} KiB)")
    with tempfile.TemporaryDirectory() as tmp:
        write_batch_profiles(tmp)
        batch = load_batch([tmp])
        for src in batch.sources:   # the profiles lived in a temporary directory: name them by file alone
            src.path = Path(src.path).name
        page = batch_report_html(batch, {**CONDITIONS, "certificate_number": "EX-004"}, issued=ISSUED)
    atomic_write(out / "report-batch.html", lambda fh: fh.write(page), text=True)
    print(f"wrote {out / 'report-batch.html'} ({len(page) // 1024} KiB)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent)
