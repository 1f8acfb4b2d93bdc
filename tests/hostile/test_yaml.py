"""Hostile YAML: profiles and rotary campaigns through the one safe loader (accelrig.safe_yaml)."""

from __future__ import annotations

import pytest

from hostile.support import assert_refused, snapshot

LAUGHS = "a: &a [x,x,x,x,x,x,x,x,x]\n" + "".join(
    f"b{i}: &b{i} [" + ",".join([f"*{'a' if i == 0 else f'b{i - 1}'}"] * 9) + "]\n" for i in range(9))


def _hostile_profiles(base: str) -> dict[str, tuple[str, str]]:
    """name -> (file text, the cause the one line must name)."""
    return {
        "alias bomb": (LAUGHS, "aliases"),
        "alias bomb in a field": (base.replace("  procedure: static\n", "  procedure: &p static\n"
                                               + "".join(f"  x{i}: &x{i} [" + ",".join(
                                                   [f"*{'p' if i == 0 else f'x{i - 1}'}"] * 10) + "]\n"
                                                   for i in range(8)), 1), "aliases"),
        "deep nesting": ("a: " + "[" * 100000 + "]" * 100000 + "\n", "nested more than"),
        "deep mapping": ("".join("  " * i + f"k{i}:\n" for i in range(60)) + "  " * 60 + "v: 1\n", "nested more than"),
        "4300-digit integer": (base.replace("  g: 9.80665\n", "  g: " + "9" * 4400 + "\n", 1), "characters"),
        "float beyond double": (base.replace("  g: 9.80665\n", "  g: 1.0e+999\n", 1), "too large"),
        "python tag": (base.replace("units: m/s^2", "units: !!python/object/apply:os.system [true]"),
                       "plain data only"),
        "duplicate key": (base.replace("  g: 9.80665\n", "  g: 9.80665\n  g: 9.81\n", 1), "calibration.g: key given"),
        "two documents": (base + "---\n" + base, "more than one YAML document"),
        "a list": ("- 1\n- 2\n", "expected a mapping"),
        "tab indentation": ("a:\n\t- 1\n", "not valid YAML"),
        "binary": ("\x00\x01\x02", "not valid YAML|not a text file|NUL bytes"),
        "empty": ("", "the file is empty"),
        "collection as key": ("? [a, b]\n: 1\n", "must be plain text"),
    }


CASES = sorted(_hostile_profiles("").keys())


@pytest.mark.parametrize("case", CASES)
def test_hostile_profile_is_refused_by_validate(case, guarded, tmp_path, profile_text):
    text, cause = _hostile_profiles(profile_text)[case]
    path = tmp_path / "p.yaml"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    before = snapshot(tmp_path)
    result = guarded("profile", "validate", path)
    assert_refused(result, cause)
    assert snapshot(tmp_path) == before


def test_validate_reports_every_file(cli, tmp_path, profile_text):
    good = tmp_path / "good.yaml"
    good.write_text(profile_text)
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(LAUGHS)
    deep = tmp_path / "deep.yaml"
    deep.write_text("[" * 5000 + "]" * 5000)
    folder = tmp_path / "folder.yaml"
    folder.mkdir()
    result = cli("profile", "validate", bomb, good, deep, folder, tmp_path / "missing.yaml")
    assert result.returncode != 0
    errors = result.stderr.splitlines()
    assert len(errors) == 4 and all(line.startswith("accelrig: error: ") for line in errors)
    assert all(str(p) in line for p, line in zip((bomb, deep, folder, tmp_path / "missing.yaml"), errors, strict=True))
    assert result.stdout.startswith(f"{good}: ok")


def test_an_alias_bomb_in_the_store_is_named_not_a_hang(limited, guarded, tmp_path):
    store = tmp_path / "store"
    (store / "dev-12345678").mkdir(parents=True)
    (store / "dev-12345678" / "20260101T000000Z-static.yaml").write_text(LAUGHS)
    result = limited("profile", "list", "--store", store, timeout=15)   # a real process: skipped and named
    assert result.returncode == 0 and "aliases" in result.stderr and "Traceback" not in result.stderr
    for command in (("profile", "show", "dev"), ("profile", "diff", "dev", "dev")):
        assert_refused(guarded(*command, "--store", store), "aliases")


def test_yaml_dump_anchors_still_load(tmp_path):
    """yaml.safe_dump writes an anchor for a list used twice: small aliases are plain data, not a bomb."""
    import yaml

    from accelrig.safe_yaml import load_yaml

    shared = [1, 2, 3]
    text = yaml.safe_dump({"a": shared, "b": shared})
    assert "&" in text
    assert load_yaml(text) == {"a": [1, 2, 3], "b": [1, 2, 3]}


# ------------------------------------------------------------------ rotary campaigns

CAMPAIGN = "name: {name}\nnominal_rate: 1660\nradius: 0.17\ntests:\n  - {{sensor: S1, mems: m.csv, tangential: x, radial: y}}\n"


def _hostile_campaigns() -> dict[str, tuple[str | bytes | None, str]]:
    return {
        "aliased name": ("name: &n x\n" + "".join(f"n{i}: &n{i} [" + ",".join(
            [f"*{'n' if i == 0 else f'n{i - 1}'}"] * 10) + "]\n" for i in range(8)) + "tests: []\n", "aliases"),
        "deep": ("tests: " + "[" * 50000 + "]" * 50000, "nested more than"),
        "huge number": (CAMPAIGN.format(name="x").replace("1660", "1" * 5000), "characters"),
        "binary": (b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe", "not a text file"),
        "a folder": (None, "is a directory"),
        "coverage factor -2": (CAMPAIGN.format(name="x") + "coverage_factor: -2\n", "coverage_factor"),
        "coverage factor 0": (CAMPAIGN.format(name="x") + "coverage_factor: 0\n", "coverage_factor"),
        "negative tolerance": (CAMPAIGN.format(name="x") + "amplitude_tolerance: -0.1\n", "amplitude_tolerance"),
        "correlation 3": (CAMPAIGN.format(name="x") + "correlation: 3\n", "correlation"),
        "radius in mm": (CAMPAIGN.format(name="x").replace("radius: 0.17", "radius: 170"), "radius"),
        "nan rate": (CAMPAIGN.format(name="x").replace("1660", ".nan"), "nominal_rate"),
        "tests a string": ("tests: many\n", "tests"),
        "a duplicate key": (CAMPAIGN.format(name="x") + "name: y\n", "name: key given twice"),
    }


@pytest.mark.parametrize("case", sorted(_hostile_campaigns()))
def test_hostile_campaign_is_refused(case, guarded, tmp_path):
    content, cause = _hostile_campaigns()[case]
    path = tmp_path / "campaign.yaml"
    if content is None:
        path.mkdir()
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    before = snapshot(tmp_path)
    result = guarded("calibrate", "rotary", "--campaign", path, "-o", tmp_path / "report.md")
    assert_refused(result, cause)
    assert snapshot(tmp_path) == before


# ------------------------------------------------------------------ the daemon's configuration

@pytest.mark.parametrize("content, cause", [
    (LAUGHS, "aliases"),
    ("devices: " + "[" * 50000 + "]" * 50000, "nested more than"),
    ("output: x\noutput: y\n", "output: key given twice"),
    ("x: 1.0e+999\n", "too large for a 64-bit float"),
])
def test_hostile_daemon_config_is_refused(content, cause, guarded, tmp_path):
    path = tmp_path / "daemon.yaml"
    path.write_text(content)
    before = snapshot(tmp_path)
    assert_refused(guarded("daemon", "check", path), cause)
    assert snapshot(tmp_path) == before
