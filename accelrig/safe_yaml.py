"""The one YAML loader for files a person hands accelrig (ground floor): profiles, campaigns, daemon configs.

``yaml.safe_load`` builds no Python objects, but it still expands aliases (a
12 KB "billion laughs" file becomes 10^9 nodes), recurses once per nesting
level (a few thousand ``[`` raise RecursionError) and turns a 5000-digit
number into a ValueError.  ``load_yaml`` first reads the file's event stream,
which is flat and costs memory only for the current event, and refuses before
anything is built:

* aliases that expand to more than MAX_NODES values (yaml.safe_dump writes an
  anchor for a list used twice, so small aliases pass),
* nesting deeper than MAX_DEPTH,
* a number longer than MAX_NUMBER_CHARS characters, or one too large for a float,
* a document larger than MAX_BYTES or holding more than one document,
* a key given twice (YAML keeps the last silently),
* a tag that would construct an object.

Every refusal is one line of the caller's error class naming the file and line.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import yaml

from accelrig.errors import AccelrigError, DataError
from accelrig.files import read_text_file

# libyaml's parser when PyYAML was built with it (ten times faster); the same events and data either way
LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

MAX_BYTES = 4 * 1024 * 1024     # a profile is ~10 KB; a campaign of hundreds of tests ~100 KB
MAX_DEPTH = 32                   # a profile nests 6 deep, a campaign 3
MAX_NODES = 200_000              # values after aliases are expanded; a profile has ~400, a big campaign a few 1000
MAX_NUMBER_CHARS = 40            # float64 needs 17 significant digits; 40 leaves room for 0.000... and exponents

# the YAML 1.1 number forms of the safe resolver (decimal, 0x, 0o, sexagesimal, .inf/.nan are words, not digits)
_NUMBER = re.compile(r"[-+]?(\.?[0-9][0-9_]*|0x[0-9a-fA-F_]+|0o?[0-7_]+|0b[01_]+)(\.[0-9_]*)?([eE][-+]?[0-9]+)?"
                     r"(:[0-5]?[0-9])*(\.[0-9_]*)?")


def load_yaml_file(path: str | os.PathLike, error: type[AccelrigError] = DataError, what: str = "a YAML file"):
    """Plain data from a YAML file, or ``error`` in one line naming the file (and the line) and why."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError:
        size = 0   # read_text_file says what is wrong (missing, unreadable)
    if size > MAX_BYTES:
        raise error(f"{path}: {size} bytes is too large for {what} (at most {MAX_BYTES // (1024 * 1024)} MiB)")
    return load_yaml(read_text_file(path, error, what), str(path), error, what)


def load_yaml(text: str, source: str = "<yaml>", error: type[AccelrigError] = DataError, what: str = "a YAML file"):
    """Plain data from YAML ``text``; refuses aliases, deep nesting, huge numbers, duplicate keys, object tags."""
    if len(text) > MAX_BYTES:
        raise error(f"{source}: {len(text)} characters is too large for {what} "
                    f"(at most {MAX_BYTES // (1024 * 1024)} MiB)")
    try:
        _check_events(text, source, error)
        return yaml.load(text, Loader=LOADER)   # noqa: S506 - a safe loader: plain data only
    except yaml.constructor.ConstructorError as exc:
        raise error(f"{source}{_line(exc)}: {exc.problem}", f"{what} holds plain data only; remove the tag") from None
    except yaml.YAMLError as exc:
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        if "maximum nesting depth" in problem:
            # libyaml in PyYAML >= 6.0.4 refuses deep flow nesting while scanning ahead, before the events
            # reach the depth check: the same refusal
            raise _too_deep(f"{source}{_line(exc)}", error) from None
        raise error(f"{source}{_line(exc)}: not valid YAML ({problem})") from None
    except (RecursionError, ValueError, OverflowError, MemoryError) as exc:   # guarded above; never a traceback
        raise error(f"{source}: cannot read {what} ({type(exc).__name__})") from None


def _line(exc) -> str:
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "start_mark", None)
    return f":{mark.line + 1}" if mark is not None else ""


def _check_events(text: str, source: str, error: type[AccelrigError]) -> None:
    """One flat pass over the parser's events: refuse what would make construction or a walk explode.

    Aliases are counted at their expanded size (what a walk over the loaded data visits), so
    yaml.safe_dump's own anchors for a repeated list pass and a "billion laughs" does not.
    """
    documents = 0
    expanded = 0                       # nodes a walk over the loaded data would visit so far
    anchors: dict[str, tuple[int, int]] = {}   # anchor -> (expanded nodes, depth) of its value
    # per open collection: keys seen (a mapping) or None (a sequence); whether the next node is a
    # key (mappings alternate key, value, ...); its anchor, expanded count at its start, deepest depth below
    stack: list[dict] = []
    for event in yaml.parse(text, Loader=LOADER):
        line = event.start_mark.line + 1
        if isinstance(event, yaml.DocumentStartEvent):
            documents += 1
            if documents > 1:
                raise error(f"{source}:{line}: more than one YAML document", "keep one document per file")
            continue
        if isinstance(event, yaml.CollectionEndEvent):
            top = stack.pop()
            if top["anchor"] is not None:
                anchors[top["anchor"]] = (expanded - top["start"], top["deepest"] - len(stack))
            if stack:
                stack[-1]["deepest"] = max(stack[-1]["deepest"], top["deepest"])
            continue
        if not isinstance(event, yaml.NodeEvent):
            continue
        parent = stack[-1] if stack else None
        if parent is not None and parent["keys"] is None:
            parent["items"] += 1
        is_key = parent is not None and parent["keys"] is not None and parent["next_is_key"]
        if parent is not None and parent["keys"] is not None:
            parent["next_is_key"] = not parent["next_is_key"]
        if isinstance(event, yaml.AliasEvent):
            size, depth = anchors.get(event.anchor, (1, 0))
            expanded += size
            _check_depth(len(stack) + depth, source, line, error)
            if parent is not None:
                parent["deepest"] = max(parent["deepest"], len(stack) + depth)
        elif isinstance(event, yaml.CollectionStartEvent):
            if is_key:
                raise error(f"{source}:{line}: a mapping key must be plain text, not a collection")
            _check_depth(len(stack) + 1, source, line, error)
            mapping = isinstance(event, yaml.MappingStartEvent)
            stack.append({"keys": set() if mapping else None, "next_is_key": mapping, "anchor": event.anchor,
                          "start": expanded, "deepest": len(stack) + 1, "path": _child_path(parent),
                          "last_key": None, "items": 0})
            expanded += 1
        elif isinstance(event, yaml.ScalarEvent):
            expanded += 1
            if event.anchor is not None:
                anchors[event.anchor] = (1, 0)
            if is_key:
                if event.value in parent["keys"]:
                    where = f"{parent['path']}.{event.value}" if parent["path"] else event.value
                    raise error(f"{source}:{line}: {where}: key given twice")
                parent["keys"].add(event.value)
                parent["last_key"] = event.value
            if not event.style and event.implicit[0]:   # plain (libyaml says "", PyYAML None)
                _check_number(event.value, f"{source}:{line}", error)
        if expanded > MAX_NODES:
            raise error(f"{source}:{line}: more than {MAX_NODES} values once its aliases (*) are expanded",
                        "an accelrig file holds a few thousand at most; is it an alias bomb?")


def _child_path(parent: dict | None) -> str:
    """Dotted path of the collection that starts now under ``parent`` (for messages)."""
    if parent is None:
        return ""
    if parent["keys"] is None:
        return f"{parent['path']}[{parent['items'] - 1}]"
    key = str(parent["last_key"])
    return f"{parent['path']}.{key}" if parent["path"] else key


def _check_depth(depth: int, source: str, line: int, error: type[AccelrigError]) -> None:
    if depth > MAX_DEPTH:
        raise _too_deep(f"{source}:{line}", error)


def _too_deep(where: str, error: type[AccelrigError]) -> AccelrigError:
    return error(f"{where}: nested more than {MAX_DEPTH} levels deep", "no accelrig file nests this deep; is it the right file?")


def _check_number(value: str, where: str, error: type[AccelrigError]) -> None:
    if not _NUMBER.fullmatch(value):
        return
    if len(value) > MAX_NUMBER_CHARS:
        raise error(f"{where}: the number {value[:20]}... has {len(value)} characters, more than a measurement needs",
                    "give at most 17 significant digits")
    resolved = yaml.safe_load(value)
    if isinstance(resolved, float) and not math.isfinite(resolved):
        raise error(f"{where}: the number {value} is too large for a 64-bit float")
