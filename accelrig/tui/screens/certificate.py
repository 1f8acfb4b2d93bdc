"""The certificate key of the results screens: ask where, then write it through accelrig.report.

The certificate is the one ``accelrig report`` writes (same renderer, same
figures); the TUI only asks who it is for and who issues it (the command's
condition flags, as a form), the path, confirms an overwrite and says what
happened.  A PDF is printed by headless Chromium: without one the operator is
told so before anything is drawn, and .html is offered instead.
"""

from __future__ import annotations

import asyncio
import re
from pathlib import Path

from rich.markup import escape

from accelrig.errors import AccelrigError
from accelrig.report import certificate, from_result, write_certificate
from accelrig.report.conditions import CONDITION_SETTINGS, conditions_from_values
from accelrig.tui.screens.dialogs import ConfirmScreen, PathScreen, SettingsForm


def file_stem(identity) -> str:
    """A device identity as a file-name part (letters, digits, _ . -), "device" when there is none."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", str(identity or "device")).strip("-") or "device"


def default_certificate_path(directory: Path, result, device: dict | None) -> Path:
    """``<identity>-<procedure>-certificate.pdf`` in ``directory``; .html when no browser can print a PDF."""
    suffix = ".pdf" if certificate.find_browser() else ".html"
    return Path(directory) / f"{file_stem((device or {}).get('identity'))}-{result.procedure}-certificate{suffix}"


async def write_certificate_flow(screen, result, recording, device: dict | None, set_status) -> Path | None:
    """Ask for the path (``screen.app`` pushes the dialogs), write the certificate off the UI thread, and
    report through ``set_status``; returns the path written, or None."""
    app = screen.app
    # who it is for and who issues it: the flags of `accelrig report`, kept for the next certificate
    remembered = app.setting_texts.get("certificate", {})
    answer = await app.push_screen_wait(SettingsForm(
        "Certificate: who it is for and who issues it", CONDITION_SETTINGS, remembered, remembered=remembered,
        note="blank fields are left out of the certificate; who authorises it, left blank, leaves the name to "
             "fill in by hand", verb="Continue"))
    if answer is None:
        set_status("no certificate written")
        return None
    values, texts = answer
    app.remember_settings("certificate", {s.name: texts[s.name] for s in CONDITION_SETTINGS if s.remembered})
    default = default_certificate_path(app.output_dir, result, device)
    prompt = ("Write the certificate to (.pdf or .html):" if certificate.find_browser() else
              "Write the certificate to (.html; no Chromium is installed here, so a .pdf cannot be printed):")
    path = await app.push_screen_wait(PathScreen(prompt, str(default), verb="Write"))
    if path is None:
        set_status("no certificate written")
        return None
    target = Path(path).expanduser()
    if target.exists() and not await app.push_screen_wait(
            ConfirmScreen(f"{target} exists. Overwrite it?", "Overwrite", "Keep it")):
        set_status(f"no certificate written: {escape(str(target))} kept as it was")
        return None
    set_status(f"writing the certificate to {escape(str(target))} ...")
    source = from_result(result, recording, device=device)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        await asyncio.to_thread(write_certificate, source, target, conditions_from_values(values))
    except (AccelrigError, OSError) as exc:
        set_status(f"[red]no certificate written:[/] {escape(str(exc))}")
        return None
    set_status(f"[green]certificate written to[/] {escape(str(target))}")
    return target
