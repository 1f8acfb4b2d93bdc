"""Render a certificate to HTML, or to PDF by printing that HTML in headless Chromium."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from datetime import datetime
from pathlib import Path

from accelrig.errors import AccelrigError, DataError
from accelrig.files import atomic_write
from accelrig.report.html import render_html
from accelrig.report.source import Source

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
# Headless, offline, nothing remembered: the page has no external resource and the browser must not phone home.
BROWSER_FLAGS = ("--headless", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-pdf-header-footer")
PRINT_TIMEOUT_S = 120


def certificate_html(src: Source, conditions: dict | None = None, figures: bool = True,
                     issued: datetime | None = None, tell: Callable[[str], None] | None = None) -> str:
    """The certificate's page; ``tell`` hears what is being done when it takes long and, one line each, every
    figure that cannot be shown and why (the page says so too)."""
    drawn, missing = None, None
    if figures:
        from accelrig.report.figures import figures_for

        drawn, missing = figures_for(src, tell)
        if tell is not None:
            for reason in missing:
                tell(f"figure not shown: {reason}")
    return render_html(src, conditions, drawn, missing, issued)


def find_browser() -> str | None:
    override = os.environ.get("ACCELRIG_CHROMIUM")
    if override:
        return override
    return next((p for p in map(shutil.which, BROWSERS) if p), None)


def require_browser() -> str:
    """The browser that prints PDFs, or the error saying how to get one (asked before any work is done)."""
    browser = find_browser()
    if browser is None:
        raise AccelrigError("a PDF needs Chromium (headless) to print the HTML, and none was found",
                            "install it (Debian: apt-get install chromium), or write .html and print that")
    return browser


def browser_command(browser: str, profile_dir: str) -> list[str]:
    cmd = [browser, *BROWSER_FLAGS, f"--user-data-dir={profile_dir}"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        cmd.append("--no-sandbox")   # Chromium refuses to run as root with its sandbox
    return cmd


def html_to_pdf(html_path: Path, pdf_path: Path) -> None:
    browser = require_browser()
    with tempfile.TemporaryDirectory(prefix="accelrig-chromium-") as profile:
        cmd = browser_command(browser, profile) + [f"--print-to-pdf={pdf_path}", html_path.resolve().as_uri()]
        try:
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=PRINT_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            raise AccelrigError(f"Chromium did not print the PDF within {PRINT_TIMEOUT_S} s") from None
        except OSError as exc:
            raise AccelrigError(f"could not start the browser {browser}: {exc.strerror}",
                                "install chromium, or point ACCELRIG_CHROMIUM at a Chromium or Chrome") from None
    if done.returncode != 0 or not pdf_path.exists() or pdf_path.stat().st_size == 0:
        tail = (done.stderr or "").strip().splitlines()[-3:]
        raise AccelrigError(f"Chromium failed to print the PDF (exit {done.returncode}): {' | '.join(tail)}")


def write_certificate(src: Source, path: str | os.PathLike, conditions: dict | None = None,
                      figures: bool = True, tell: Callable[[str], None] | None = None) -> None:
    """Write FILE.html or FILE.pdf (chosen by the suffix), whole or not at all; ``tell`` as for
    certificate_html."""
    write_page(lambda: certificate_html(src, conditions, figures, tell=tell), path)


def write_page(render, path: str | os.PathLike) -> None:
    """Write the page ``render()`` returns as FILE.html, or printed as FILE.pdf (by the suffix), whole or not
    at all; the suffix and the browser are checked before anything is rendered."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".html", ".htm", ".pdf"):
        raise DataError(f"{path}: the certificate's format follows the suffix", "use .html or .pdf")
    if suffix == ".pdf":
        require_browser()   # before the figures are drawn: a missing browser is known at once
    page = render()
    if suffix != ".pdf":
        atomic_write(path, lambda fh: fh.write(page), text=True)
        return
    with tempfile.TemporaryDirectory(prefix="accelrig-report-") as tmp:
        html_path, pdf_tmp = Path(tmp) / "certificate.html", Path(tmp) / "certificate.pdf"
        html_path.write_text(page, encoding="utf-8")
        html_to_pdf(html_path, pdf_tmp)
        data = pdf_tmp.read_bytes()
    atomic_write(path, lambda fh: fh.write(data), text=False)
