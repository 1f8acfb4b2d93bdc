"""Every accelrig name the operator docs tell people to import or call exists: a renamed or moved function
leaves the docs' commands failing with an ImportError (docs/rotary.md's campaign demo named a module the
function had left)."""

import importlib
import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "docs").glob("*.yaml"))]


def named_in(text: str) -> set[str]:
    """Dotted accelrig names: ``from accelrig.x import a, b`` (code and python -c lines) and `accelrig.x.y`."""
    names = set()
    for m in re.finditer(r"from (accelrig[\w.]*) import ([\w, ]+)", text):
        names.update(f"{m.group(1)}.{n.strip()}" for n in m.group(2).split(",") if n.strip())
    names.update(m.group(1) for m in re.finditer(r"`(accelrig(?:\.\w+)+)", text))
    return names


def resolves(dotted: str) -> bool:
    """The longest importable module prefix, then attributes for the rest."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for part in parts[i:]:
                obj = getattr(obj, part)
        except AttributeError:
            return False
        return True
    return False


def test_every_accelrig_name_in_the_docs_exists():
    entry_point_groups = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"])
    missing = sorted((doc.name, name) for doc in DOCS for name in named_in(doc.read_text())
                     if name not in entry_point_groups and not resolves(name))
    assert not missing, f"the docs name what the code does not have: {missing}"


def test_the_check_finds_a_moved_function():
    assert named_in('python -c "from accelrig.sim.rigs.rotary import write_sim_campaign; x()"') == {
        "accelrig.sim.rigs.rotary.write_sim_campaign"}
    assert not resolves("accelrig.sim.rigs.rotary.write_sim_campaign")
    assert resolves("accelrig.sim.campaign.write_sim_campaign")
