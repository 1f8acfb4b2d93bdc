"""The progress line of long command-line work: on a terminal only, never under CI, erased at the end."""

import re
import time

from accelrig.commands.progress import Progress


class Terminal:
    def __init__(self, tty=True):
        self.tty, self.text = tty, ""

    def isatty(self):
        return self.tty

    def write(self, text):
        self.text += text

    def flush(self):
        pass


def test_long_work_on_a_terminal_shows_seconds_and_detail_then_erases_the_line(monkeypatch):
    monkeypatch.delenv("CI", raising=False)
    term = Terminal()
    with Progress("fitting the wheel", stream=term, show_after=0.05) as progress:
        progress.step("test 2 done")
        # until the line is drawn (its thread can start late on a loaded machine: a fixed 0.3 s raced it)
        deadline = time.monotonic() + 30
        while "test 2 done" not in term.text and time.monotonic() < deadline:
            time.sleep(0.01)
    assert re.search(r"fitting the wheel \.\.\. \d+ s  test 2 done", term.text), term.text
    assert term.text.endswith("\r")   # the line is blanked: what is printed next stands alone


def test_quick_work_pipes_and_ci_print_nothing(monkeypatch):
    monkeypatch.delenv("CI", raising=False)
    quick, pipe = Terminal(), Terminal(tty=False)
    with Progress("quick", stream=quick):
        pass
    with Progress("piped", stream=pipe, show_after=0.0):
        time.sleep(0.1)
    monkeypatch.setenv("CI", "true")
    ci = Terminal()
    with Progress("ci", stream=ci, show_after=0.0):
        time.sleep(0.1)
    assert quick.text == pipe.text == ci.text == ""
