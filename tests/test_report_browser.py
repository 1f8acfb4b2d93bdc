"""Certificates in a real browser: headless Chromium renders the HTML to a PNG with no console message and
no request outside the page, and prints the PDF whose pages pdftoppm counts.  One module, three browser
starts (each costs a second or two)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess

import pytest

from accelrig.report import certificate_html, from_result, write_certificate
from accelrig.report.certificate import browser_command, find_browser
from report_support import DEVICE, rotary_campaign_result, static_result

BROWSER = find_browser()
if BROWSER is None or shutil.which("pdftoppm") is None:
    if os.environ.get("CI"):
        pytest.fail("CI must install chromium and poppler-utils (.ci/run does)", pytrace=False)
    pytest.skip("chromium or pdftoppm is not installed (Debian: apt-get install chromium poppler-utils); "
                "CI installs them and runs these tests", allow_module_level=True)
pytest.importorskip("matplotlib")

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def render_png(html_path, png_path, tmp_path) -> str:
    """Screenshot the page; return Chromium's log (console messages appear there as CONSOLE lines)."""
    cmd = browser_command(BROWSER, str(tmp_path / "profile")) + [
        "--enable-logging=stderr", "--v=0", "--window-size=1000,4000", f"--screenshot={png_path}",
        html_path.resolve().as_uri()]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stderr


def console_messages(log: str) -> list[str]:
    return [line for line in log.splitlines() if "CONSOLE" in line or "Uncaught" in line]


@pytest.fixture(scope="module")
def campaign_page(tmp_path_factory):
    d = tmp_path_factory.mktemp("browser")
    result, _ = rotary_campaign_result(d / "campaign")
    page = d / "campaign.html"
    page.write_text(certificate_html(from_result(result)))
    return page


def test_certificate_is_self_contained(campaign_page):
    html = campaign_page.read_text()
    # nothing to fetch: no script, stylesheet link, image or font from outside (SVG namespaces are names, not requests)
    assert not re.search(r"<(script|link|img|iframe)\b", html)
    assert not re.search(r"""(src|href)\s*=\s*["'](https?:|//|file:)""", html)
    assert "url(http" not in html and "@import" not in html


def test_chromium_renders_the_campaign_certificate_without_console_messages(campaign_page, tmp_path):
    # the check itself must be able to fail: a page that logs an error is caught in the same browser run
    bad = tmp_path / "bad.html"
    bad.write_text(campaign_page.read_text().replace("</body>", "<script>console.error('oops')</script></body>"))
    png = tmp_path / "campaign.png"
    log = render_png(campaign_page, png, tmp_path)
    assert console_messages(log) == [], console_messages(log)
    data = png.read_bytes()
    assert data.startswith(PNG_MAGIC) and len(data) > 50_000   # a rendered page, not a blank one
    bad_log = render_png(bad, tmp_path / "bad.png", tmp_path)
    assert any("oops" in m for m in console_messages(bad_log))


def test_pdf_prints_and_pdftoppm_counts_its_pages(tmp_path):
    result, rec = static_result()
    pdf = tmp_path / "static.pdf"
    write_certificate(from_result(result, rec, device=DEVICE), pdf, {"operator": "A. Tester"})
    assert pdf.read_bytes().startswith(b"%PDF")
    subprocess.run(["pdftoppm", "-r", "30", "-png", str(pdf), str(tmp_path / "page")], check=True, timeout=120)
    pages = sorted(tmp_path.glob("page*.png"))
    # A4 at 12 mm margins: the static certificate's tables fill two to three pages (the wizard's fifteen holds:
    # more checks to state, and an axis whose shape went unchecked adds its allowance sentence), the figure a
    # page at most
    assert 2 <= len(pages) <= 4, len(pages)
    # each page is a page of the certificate, not a blank sheet
    assert all(p.stat().st_size > 1000 for p in pages)


def test_pdf_breaks_no_value_unit_or_part_name_at_its_hyphen(tmp_path):
    """The browser may break a line after any hyphen: "ICM-" at a line's end and "20948" on the next, or
    "-" and "0.15".  Each token with a hyphen in it is kept whole (report.wording.html_text): in the printed
    PDF no line ends in a hyphen.  A warning of many part names and negative numbers fills several lines, so
    a break inside one of them was all but certain before."""
    if shutil.which("pdftotext") is None:
        pytest.skip("pdftotext (poppler-utils) is not installed")
    result, rec = static_result()
    result.warnings.append("the offsets of " + ", ".join(f"ICM-20948 unit {i} moved by -0.{i}5 m/s^2"
                                                           for i in range(1, 30)))
    pdf = tmp_path / "static.pdf"
    write_certificate(from_result(result, rec, device={**DEVICE, "chip": "ICM-20948"}), pdf,
                      {"certificate_number": 'C-7 "b"', "approved_by": "Dr. A. Weber"}, figures=False)
    text = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True, check=True,
                          timeout=120).stdout
    assert "ICM-20948 unit 29" in text   # the warning is there, whole
    broken = [line for line in text.splitlines() if re.search(r"\S-$", line.rstrip())]
    assert broken == [], broken
    # every page names the certificate and says which page of how many (ISO/IEC 17025 7.8.2.1), and the
    # person who authorises it is named above the signature line
    pages = text.count("\f") + (not text.endswith("\f"))
    footers = re.findall(r'No\. C-7 "b" · Page (\d+) of (\d+)', text)
    assert [int(p) for p, _ in footers] == list(range(1, pages + 1)) and {int(n) for _, n in footers} == {pages}
    assert re.search(r"Approved by\s+Dr\. A\. Weber", text) and "Signature" in text
