"""Declarative validation of plain data (ground floor): one description checks a value and publishes itself as JSON Schema.

Used by the profile schema, the rotary campaign files and the daemon config.  Each
node knows how to check a value (raising :class:`Invalid` with the dotted path of
the field and what was wrong) and how to describe itself as JSON Schema (draft
2020-12).  ``check(spec, value, error)`` is the entry point: it raises ``error``
(an AccelrigError class) with one line naming the field.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from datetime import UTC, datetime

from accelrig.errors import AccelrigError


def check(spec: Spec, value, error: type[AccelrigError], where: str = "") -> None:
    """Validate ``value`` against ``spec``; on failure raise ``error`` naming the field (prefixed by ``where``)."""
    try:
        spec.check(value, "")
    except Invalid as exc:
        raise error(f"{where}{exc}") from None


# ----------------------------------------------------------------- describing values


def describe(value) -> str:
    """How a wrong value looks, for messages: '3x2', 'a string', 'null'..."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"a boolean ({value})"
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, str):
        shown = value if len(value) <= 40 else value[:37] + "..."
        return f"the string {shown!r}"
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        shape = _list_shape(value)
        return shape if shape else f"a list of {len(value)}"
    return f"a {type(value).__name__}"


def _list_shape(value: list) -> str | None:
    """'3', '3x2' for rectangular lists of numbers, else None."""
    if all(is_number(v) for v in value):
        return f"a list of {len(value)} numbers"
    if all(isinstance(v, list) for v in value) and value:
        widths = {len(v) for v in value}
        if len(widths) == 1 and all(is_number(x) for v in value for x in v):
            return f"{len(value)}x{widths.pop()}"
        return f"{len(value)} rows of lengths {'/'.join(str(len(v)) for v in value)}"
    return None


def is_number(value) -> bool:
    # bool is an int in Python but never a number in a profile.
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def join_path(path: str, key) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


class Invalid(ValueError):
    """A value breaks its spec: ``path`` (dotted, with [i] for list items) and what was wrong.

    Nodes raise this; ``check`` turns it into the caller's error class (ProfileError for
    profiles, DataError for campaigns, ...), so one validator serves every file kind.
    """

    def __init__(self, path: str, problem: str):
        super().__init__(f"{path or '(top level)'}: {problem}")
        self.path = path
        self.problem = problem


def fail(path: str, problem: str) -> None:
    raise Invalid(path, problem)


# ----------------------------------------------------------------- value kinds


class Spec:
    """A node of the schema description."""

    description: str = ""

    def check(self, value, path: str) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def json_schema(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError

    def _with_description(self, schema: dict) -> dict:
        if self.description:
            schema["description"] = self.description
        return schema


@dataclass
class Number(Spec):
    description: str = ""
    minimum: float | None = None
    exclusive_minimum: float | None = None
    maximum: float | None = None

    def check(self, value, path: str) -> None:
        if not is_number(value):
            fail(path, f"expected a number, got {describe(value)}")
        if not math.isfinite(value):
            fail(path, f"expected a finite number, got {value}")
        if self.minimum is not None and value < self.minimum:
            fail(path, f"expected a number >= {self.minimum:g}, got {value!r}")
        if self.exclusive_minimum is not None and value <= self.exclusive_minimum:
            fail(path, f"expected a number > {self.exclusive_minimum:g}, got {value!r}")
        if self.maximum is not None and value > self.maximum:
            fail(path, f"expected a number <= {self.maximum:g}, got {value!r}")

    def json_schema(self) -> dict:
        s: dict = {"type": "number"}
        if self.minimum is not None:
            s["minimum"] = self.minimum
        if self.exclusive_minimum is not None:
            s["exclusiveMinimum"] = self.exclusive_minimum
        if self.maximum is not None:
            s["maximum"] = self.maximum
        return self._with_description(s)


@dataclass
class Integer(Spec):
    description: str = ""
    minimum: int | None = None
    maximum: int | None = None

    def check(self, value, path: str) -> None:
        if not isinstance(value, int) or isinstance(value, bool):
            fail(path, f"expected an integer, got {describe(value)}")
        if self.minimum is not None and value < self.minimum:
            fail(path, f"expected an integer >= {self.minimum}, got {value}")
        if self.maximum is not None and value > self.maximum:
            fail(path, f"expected an integer <= {self.maximum}, got {value}")

    def json_schema(self) -> dict:
        s: dict = {"type": "integer"}
        if self.minimum is not None:
            s["minimum"] = self.minimum
        if self.maximum is not None:
            s["maximum"] = self.maximum
        return self._with_description(s)


@dataclass
class String(Spec):
    description: str = ""
    enum: tuple[str, ...] | None = None
    pattern: str | None = None
    min_length: int = 0

    def check(self, value, path: str) -> None:
        if not isinstance(value, str):
            fail(path, f"expected a string, got {describe(value)}")
        if self.enum is not None and value not in self.enum:
            fail(path, f"expected one of {', '.join(repr(e) for e in self.enum)}, got {value!r}")
        if len(value) < self.min_length:
            fail(path, "expected a non-empty string")
        if self.pattern is not None and not re.fullmatch(self.pattern, value):
            fail(path, f"{value!r} does not match the pattern {self.pattern}")

    def json_schema(self) -> dict:
        s: dict = {"type": "string"}
        if self.enum is not None:
            s["enum"] = list(self.enum)
        if self.min_length:
            s["minLength"] = self.min_length
        if self.pattern is not None:
            s["pattern"] = f"^(?:{self.pattern})$"
        return self._with_description(s)


@dataclass
class Boolean(Spec):
    description: str = ""

    def check(self, value, path: str) -> None:
        if not isinstance(value, bool):
            fail(path, f"expected true or false (yes or no), got {describe(value)}")

    def json_schema(self) -> dict:
        return self._with_description({"type": "boolean"})


@dataclass
class DateTime(Spec):
    """A UTC date-time string, 2026-11-22T03:25:00Z (kept a string so YAML never makes it a datetime)."""

    description: str = ""

    PATTERN = r"\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d+)?Z"

    def check(self, value, path: str) -> None:
        if not isinstance(value, str) or not re.fullmatch(self.PATTERN, value):
            fail(path, f"expected a UTC date-time like 2026-11-22T03:25:00Z, got {describe(value)}")
        try:
            parse_datetime(value)
        except ValueError as exc:
            fail(path, f"not a valid date-time ({exc})")

    def json_schema(self) -> dict:
        return self._with_description({"type": "string", "pattern": f"^{self.PATTERN}$"})


def parse_datetime(text: str) -> datetime:
    """A profile date-time (or a plain date, or any ISO form) as an aware UTC datetime."""
    value = datetime.fromisoformat(text.replace("Z", "+00:00"))
    if value.tzinfo is None:
        value = value.replace(tzinfo=UTC)
    return value.astimezone(UTC)


def format_datetime(value: datetime) -> str:
    return value.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


@dataclass
class Const(Spec):
    value: object = None
    description: str = ""

    def check(self, value, path: str) -> None:
        if value != self.value or isinstance(value, bool) != isinstance(self.value, bool):
            fail(path, f"expected {self.value!r}, got {describe(value)}")

    def json_schema(self) -> dict:
        return self._with_description({"const": self.value})


@dataclass
class Array(Spec):
    """Numbers of a fixed shape: (n,) vector or (rows, cols) matrix; None = any length."""

    shape: tuple[int | None, ...] = (None,)
    description: str = ""
    minimum: float | None = None

    def _expected(self) -> str:
        if len(self.shape) == 1:
            n = self.shape[0]
            return f"expected a list of {n} numbers" if n is not None else "expected a list of numbers"
        if self.shape[0] is None:
            return "expected a square matrix of numbers"
        return f"expected {self.shape[0]}x{self.shape[1]} numbers"

    def check(self, value, path: str) -> None:
        expected = self._expected()
        if not isinstance(value, list):
            fail(path, f"{expected}, got {describe(value)}")
        rows = self.shape[0]
        if rows is not None and len(value) != rows:
            fail(path, f"{expected}, got {describe(value)}")
        if len(self.shape) == 1:
            for i, v in enumerate(value):
                self._check_number(v, join_path(path, i))
            return
        cols = self.shape[1] if self.shape[1] is not None else len(value)  # None: square
        if not all(isinstance(row, list) and len(row) == cols for row in value):
            fail(path, f"{expected}, got {describe(value)}")
        for i, row in enumerate(value):
            for j, v in enumerate(row):
                self._check_number(v, f"{path}[{i}][{j}]")

    def _check_number(self, v, path: str) -> None:
        if not is_number(v):
            fail(path, f"expected a number, got {describe(v)}")
        if not math.isfinite(v):
            fail(path, f"expected a finite number, got {v}")
        if self.minimum is not None and v < self.minimum:
            fail(path, f"expected a number >= {self.minimum:g}, got {v!r}")

    def json_schema(self) -> dict:
        item: dict = {"type": "number"}
        if self.minimum is not None:
            item["minimum"] = self.minimum
        for size in reversed(self.shape):
            node: dict = {"type": "array", "items": item}
            if size is not None:
                node["minItems"] = size
                node["maxItems"] = size
            item = node
        return self._with_description(item)


@dataclass
class ListOf(Spec):
    item: Spec = None
    description: str = ""

    def check(self, value, path: str) -> None:
        if not isinstance(value, list):
            fail(path, f"expected a list, got {describe(value)}")
        for i, v in enumerate(value):
            self.item.check(v, join_path(path, i))

    def json_schema(self) -> dict:
        return self._with_description({"type": "array", "items": self.item.json_schema()})


@dataclass
class Nullable(Spec):
    inner: Spec = None

    @property
    def description(self) -> str:  # type: ignore[override]
        return self.inner.description

    def check(self, value, path: str) -> None:
        if value is not None:
            self.inner.check(value, path)

    def json_schema(self) -> dict:
        inner = self.inner.json_schema()
        description = inner.pop("description", None)
        s: dict = {"anyOf": [inner, {"type": "null"}]}
        if description:
            s["description"] = description
        return s


@dataclass
class OneOf(Spec):
    """The first option whose check passes; the message names all options."""

    options: tuple[Spec, ...] = ()
    description: str = ""
    expected: str = ""

    def check(self, value, path: str) -> None:
        for option in self.options:
            try:
                option.check(value, path)
                return
            except Invalid:
                continue
        fail(path, f"expected {self.expected}, got {describe(value)}")

    def json_schema(self) -> dict:
        return self._with_description({"anyOf": [o.json_schema() for o in self.options]})


@dataclass
class Plain(Spec):
    """Free-form plain data (settings, extra quality figures): mappings with string
    keys, lists, strings, finite numbers, booleans, null.  Never dates, bytes or sets."""

    description: str = ""
    mapping: bool = False   # the value itself must be a mapping

    def check(self, value, path: str) -> None:
        if self.mapping and not isinstance(value, dict):
            fail(path, f"expected a mapping, got {describe(value)}")
        self._check_plain(value, path)

    def _check_plain(self, value, path: str) -> None:
        if value is None or isinstance(value, (bool, str)):
            return
        if is_number(value):
            if not math.isfinite(value):
                fail(path, f"expected a finite number, got {value}")
            return
        if isinstance(value, list):
            for i, v in enumerate(value):
                self._check_plain(v, join_path(path, i))
            return
        if isinstance(value, dict):
            for k, v in value.items():
                if not isinstance(k, str):
                    fail(path, f"keys must be strings, got {describe(k)}")
                self._check_plain(v, join_path(path, k))
            return
        fail(path, f"expected plain data (number, string, list, mapping), got {describe(value)}")

    def json_schema(self) -> dict:
        return self._with_description({"type": "object"} if self.mapping else {})


@dataclass
class Field:
    spec: Spec
    required: bool = True


@dataclass
class Object(Spec):
    """A mapping with known keys.  Unknown keys are refused unless ``additional``
    gives a spec for them (open maps such as method settings)."""

    fields: dict[str, Field] = field(default_factory=dict)
    description: str = ""
    additional: Spec | None = None
    key_pattern: str | None = None

    def check(self, value, path: str) -> None:
        if not isinstance(value, dict):
            fail(path, f"expected a mapping, got {describe(value)}")
        for key in value:
            if not isinstance(key, str):
                fail(path, f"keys must be strings, got {describe(key)}")
        for name, f in self.fields.items():
            if name not in value and f.required:
                fail(join_path(path, name), "missing (required field)")
        for key, v in value.items():
            if key in self.fields:
                self.fields[key].spec.check(v, join_path(path, key))
            elif self.additional is None:
                known = ", ".join(self.fields)
                fail(join_path(path, key), f"unknown key (known here: {known})")
            else:
                if self.key_pattern is not None and not re.fullmatch(self.key_pattern, key):
                    fail(join_path(path, key), f"key does not match the pattern {self.key_pattern}")
                self.additional.check(v, join_path(path, key))

    def json_schema(self) -> dict:
        s: dict = {"type": "object"}
        if self.fields:
            s["properties"] = {k: f.spec.json_schema() for k, f in self.fields.items()}
            required = [k for k, f in self.fields.items() if f.required]
            if required:
                s["required"] = required
        if self.additional is None:
            s["additionalProperties"] = False
        else:
            s["additionalProperties"] = self.additional.json_schema()
            if self.key_pattern is not None:
                s["propertyNames"] = {"pattern": f"^(?:{self.key_pattern})$"}
        return self._with_description(s)


def optional(spec: Spec) -> Field:
    return Field(spec, required=False)
