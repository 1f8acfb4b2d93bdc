"""The words a certificate hands to a customer: findings, not advice to the operator, and no broken parts.

A procedure's warnings and sentences speak to the operator at the rig: what was seen, then what to do
("...: let the sensor settle and calibrate again", "(--model six-face)").  The customer of a certificate
needs the finding, which qualifies the result, and not the action, which is the lab's business and
names options of a program they do not run.  ``as_finding`` keeps the first and drops the second, on
the text alone, so a profile written by any accelrig version reads the same.  ``html_text`` escapes for
HTML and keeps each token with a hyphen or minus in it (a part name like ICM-20948, -0.0055, a date,
9.780-9.832) on one line: the browser breaks after a hyphen, and a value split there reads wrong.
"""

from __future__ import annotations

import re
from html import escape

# the verbs an operator's advice starts with ("give the local g", "record with timestamps", "check --x")
ADVICE_VERBS = frozenset((
    "add", "calibrate", "check", "choose", "fix", "give", "hold", "increase", "install", "keep", "let",
    "mount", "move", "put", "record", "reduce", "repeat", "rerun", "re-run", "run", "set", "spin", "state",
    "try", "use", "verify", "wait"))
LEADING_JOINERS = ("or ", "and ", "then ", "so ", "else ")
# "unless g was surveyed that well, state u(g) itself": advice after a condition (the procedures write
# the comma: "to check, put one face down again")
CONDITIONS = ("unless ", "if ", "when ", "where ", "for ", "to ", "after ", "before ")
CLI_OPTION = re.compile(r"(?<![\w-])--[a-z][\w-]*")
CLI_COMMAND = re.compile(r"\baccelrig [a-z]")
# a clause ends at "; ", ": " or a sentence's ". " before a capital (not "e.g. 1e-4", not "0.5 Hz")
CLAUSE_END = re.compile(r"; |: |\. (?=[A-Z])|\? (?=[A-Z])")
HYPHENATED = re.compile(r"\S*[-\u2212\u2010]\S*")


def _is_advice(clause: str) -> bool:
    """A clause that advises: it starts with an advice verb (after a joiner or a condition), names an
    accelrig command, or is little more than an option ("--model six-face").  A finding that merely
    mentions an option ("calibrated with --range-g 4 but recorded at 8 g") is not advice: it is kept,
    the option said in words (``_options_in_words``)."""
    text = clause.strip().lower()
    for joiner in LEADING_JOINERS:
        if text.startswith(joiner):
            text = text[len(joiner):]
    if CLI_COMMAND.search(clause):
        return True
    if CLI_OPTION.search(clause) and len(CLI_OPTION.sub("", clause).split()) <= 1:
        return True
    heads = [text] + (text.split(", ")[1:] if text.startswith(CONDITIONS) else [])
    return any(re.split(r"[\s,]", head, maxsplit=1)[0] in ADVICE_VERBS for head in heads)


def _options_in_words(text: str) -> str:
    """An option a kept finding mentions, as words a customer reads: "--cross-axis-sd" -> "the cross-axis-sd
    setting"."""
    return CLI_OPTION.sub(lambda m: f"the {m.group(0)[2:]} setting", text)


def _top_level_split(text: str) -> list[tuple[str, str]]:
    """(separator before, clause) pairs at the clause ends outside parentheses; the first separator is ''."""
    parts, depth, start, sep = [], 0, 0, ""
    i = 0
    while i < len(text):
        ch = text[i]
        if ch in "([\0":   # \0 and \1: an aside already read (_drop_advice_asides)
            depth += 1
        elif ch in ")]\1":
            depth = max(0, depth - 1)
        elif depth == 0 and (m := CLAUSE_END.match(text, i)):
            parts.append((sep, text[start:i]))
            sep = m.group(0)
            start = i = m.end()
            continue
        i += 1
    parts.append((sep, text[start:]))
    return parts


def _drop_advice_asides(text: str) -> str:
    """Remove parenthesised asides that name an option or advise ("(--model six-face)", "(record with
    timestamps ...)"), innermost first; the others stay, their own advice removed."""
    pattern = re.compile(r" ?\(([^()]*)\)")
    while True:
        changed = pattern.sub(lambda m: "" if _is_advice(m.group(1)) else (
            m.group(0)[:m.start(1) - m.start(0)].replace("(", "\0") + as_finding(m.group(1)) + "\1"), text)
        if changed == text:
            return text.replace("\0", "(").replace("\1", ")")
        text = changed


def as_finding(text: str) -> str:
    """``text`` without the operator's advice: asides that name an option or advise are removed, and so is
    every clause after the first that advises (starts with an advice verb, names an accelrig command, or is
    little more than an option).  What remains is what was found, an option it mentions said in words."""
    text = str(text).strip()
    plain = _drop_advice_asides(text)
    clauses = _top_level_split(plain)
    # the first clause is what was seen (procedures say the finding first, then what to do): always kept,
    # even when it starts like advice ("hold 3 lasted 1.2 s: its mean is noisy")
    kept = clauses[:1] + [(sep, clause) for sep, clause in clauses[1:] if clause.strip() and not _is_advice(clause)]
    if not kept[0][1].strip():
        return _options_in_words(plain)
    out = _options_in_words(kept[0][1] + "".join(sep + clause for sep, clause in kept[1:]))
    out = out.rstrip(" ;:,")
    if text.endswith((".", "?")) and not out.endswith((".", "?")):
        out += "."
    return out


def display_unit(unit: str) -> str:
    """A unit as printed: powers as superscripts (m/s^2 -> m/s²)."""
    return unit.replace("^2", "²").replace("^3", "³").replace("^4", "⁴")


def html_text(value) -> str:
    """``value`` escaped for HTML, powers as superscripts, "+-" as "±", every token with a hyphen or minus in
    it kept on one line."""
    text = display_unit(str(value)).replace("+-", "±")   # the text reports' ASCII "+-" as a person writes it
    return HYPHENATED.sub(lambda m: f'<span class="nb">{m.group(0)}</span>', escape(text))
