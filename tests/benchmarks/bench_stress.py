"""Stress benchmark (issue 18): every procedure off the papers' ideal, judged against the simulator's truth.

    python tests/benchmarks/bench_stress.py [--runs 40] [--procedure static] [--condition ar1] [--seed 1]

The conditions live beside this file, one module per procedure (``stress_static.py``,
``stress_wheel.py``, ``stress_slider_crank.py``, ``stress_rotary.py``), each a list
``CONDITIONS`` of ``Condition``.  A condition's ``run(seed)`` builds a recording with the
simulator (``accelrig.sim``: trajectories differentiated numerically, a sensor model with
coloured noise, drift and per-axis noise; it imports no estimator), runs the procedure's own
code on it as the command would, and returns an ``Outcome``: for each judged parameter the
error (estimate - truth) and the stated u, the warnings and any refusal.

For each condition the table gives, over the runs:

    refused    share of runs refused, with the most common message
    warned     share of the other runs that carried a warning
    cover      coverage of +-k u over all parameters, in the runs neither refused nor warned
               (target 90-98 %); k = 2 unless the tool states its own coverage factor for the
               parameter (``Outcome.k``: Student's t on the effective dof of u^2)
    cover(w)   the same in the warned runs (may be low: the warning is what makes it honest)
    u/sd       median over parameters of rms(u) / sd(error), all unrefused runs (1 = honest)

Honesty target: coverage 90-98 % wherever the tool neither warns nor refuses; a warning in
>= 95 % of runs wherever coverage would be lower; no refusal blaming the wrong cause (each
condition names the words a right refusal must contain in ``refusal_must_say``).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

PROCEDURES = ("static", "wheel", "slider_crank", "rotary")


@dataclass
class Outcome:
    """One run: per judged parameter, error against truth and stated u; warnings; refusal."""

    errors: dict[str, float] = field(default_factory=dict)
    u: dict[str, float] = field(default_factory=dict)
    k: dict[str, float] = field(default_factory=dict)   # the coverage factor the tool states, where it does (else 2)
    warnings: list[str] = field(default_factory=list)
    refused: str | None = None
    seconds: float = 0.0


@dataclass
class Condition:
    procedure: str
    name: str
    run: Callable[[int], Outcome]
    # words a refusal must contain to blame the right cause (any of them); () = any refusal is wrong
    refusal_must_say: tuple[str, ...] = ()
    note: str = ""


def load_conditions(procedure: str | None = None) -> list[Condition]:
    found = []
    for name in PROCEDURES:
        if procedure and name != procedure:
            continue
        try:
            module = importlib.import_module(f"stress_{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"stress_{name}":
                raise
            continue
        found.extend(module.CONDITIONS)
    return found


def timed(run: Callable[[int], Outcome]) -> Callable[[int], Outcome]:
    def wrapper(seed: int) -> Outcome:
        start = time.perf_counter()
        outcome = run(seed)
        outcome.seconds = time.perf_counter() - start
        return outcome
    return wrapper


@dataclass
class Row:
    procedure: str
    condition: str
    runs: int
    refused: float
    refusal: str
    wrong_refusals: int
    warned: float
    warning: str
    cover: float
    cover_warned: float
    u_over_sd: float
    seconds: float


def _coverage(outcomes: list[Outcome]) -> float:
    hits = [abs(o.errors[k]) <= o.k.get(k, 2.0) * o.u[k] for o in outcomes for k in o.errors]
    return float(np.mean(hits)) if hits else float("nan")


def _u_over_sd(outcomes: list[Outcome]) -> float:
    if len(outcomes) < 5:
        return float("nan")
    ratios = []
    for k in outcomes[0].errors:
        e = np.array([o.errors[k] for o in outcomes if k in o.errors])
        u = np.array([o.u[k] for o in outcomes if k in o.u])
        sd = np.sqrt(np.mean(e**2))          # around the truth: a bias counts as error
        if sd > 0:
            ratios.append(np.sqrt(np.mean(u**2)) / sd)
    return float(np.median(ratios)) if ratios else float("nan")


def _short(text: str, width: int = 60) -> str:
    text = " ".join(text.split())
    return text if len(text) <= width else text[: width - 1] + "…"


def summarise(condition: Condition, outcomes: list[Outcome]) -> Row:
    refused = [o for o in outcomes if o.refused]
    kept = [o for o in outcomes if not o.refused]
    warned = [o for o in kept if o.warnings]
    clean = [o for o in kept if not o.warnings]
    wrong = sum(1 for o in refused
                if not any(w.lower() in o.refused.lower() for w in condition.refusal_must_say))
    refusal = Counter(_short(o.refused) for o in refused).most_common(1)
    warning = Counter(_short(w) for o in warned for w in o.warnings).most_common(1)
    return Row(condition.procedure, condition.name, len(outcomes),
               len(refused) / len(outcomes), refusal[0][0] if refusal else "", wrong,
               len(warned) / len(kept) if kept else float("nan"), warning[0][0] if warning else "",
               _coverage(clean), _coverage(warned), _u_over_sd(kept),
               float(np.mean([o.seconds for o in outcomes])))


def print_table(rows: list[Row]) -> None:
    print("| procedure | condition | runs | refused | wrong cause | warned | cover | cover(w) | u/sd | s/run |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        def pct(x):
            return "-" if np.isnan(x) else f"{100 * x:.0f} %"
        print(f"| {r.procedure} | {r.condition} | {r.runs} | {pct(r.refused)} | {r.wrong_refusals} | "
              f"{pct(r.warned)} | {pct(r.cover)} | {pct(r.cover_warned)} | "
              f"{'-' if np.isnan(r.u_over_sd) else f'{r.u_over_sd:.2f}'} | {r.seconds:.2f} |")
    messages = [(r, r.refusal, r.warning) for r in rows if r.refusal or r.warning]
    if messages:
        print("\nMost common message per condition:")
        for r, refusal, warning in messages:
            if refusal:
                print(f"- {r.procedure} / {r.condition}: refused: {refusal}")
            if warning:
                print(f"- {r.procedure} / {r.condition}: warned: {warning}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--procedure", choices=PROCEDURES)
    parser.add_argument("--condition", help="run only conditions whose name contains this")
    args = parser.parse_args(argv)
    conditions = [c for c in load_conditions(args.procedure)
                  if not args.condition or args.condition in c.name]
    if not conditions:
        print("no condition matches", file=sys.stderr)
        return 2
    rows = []
    for condition in conditions:
        run = timed(condition.run)
        outcomes = [run(args.seed * 100003 + i) for i in range(args.runs)]
        rows.append(summarise(condition, outcomes))
        print(f"{condition.procedure} / {condition.name}: done", file=sys.stderr, flush=True)
    print_table(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
