"""What a hostile law string can cost: random well-formed formulas over every allowed function, extreme numbers
and nesting, through parse_law, the fit's basis/fixed evaluation and the formula with parameters put in (what
``nnphd.load`` and the report do). Prints how each ended (a law, one ValueError line, anything else, a time-out)
and the slowest formulas; anything but a law or a ValueError is a defect (tests/test_lawtext.py keeps the cases
found so far).

.venv/bin/python benchmarks/fuzz_laws.py [--seed 8] [--n 1500] [--timeout 10]

Unix only (a SIGALRM time-out per formula); memory is capped at 6 GiB (RLIMIT_AS).
"""

import argparse
import random
import resource
import signal
import sys
import time
import warnings
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import numpy as np
import sympy as sp

from nnphd.explain.families import parse_law
from nnphd.explain.lawtext import FUNCTIONS

NUMBERS = ["1e308", "1e-308", "-1", "0", "0.5", "2", "100", "3", "1e30", "-2.5"]
NAMES = ["x", "x_dot", "t", "c", "m", "b", "c", "c"]


def formula(r: random.Random, depth: int) -> str:
    k = r.random()
    if depth <= 0 or k < 0.25:
        return r.choice(NAMES) if r.random() < 0.7 else r.choice(NUMBERS)
    if k < 0.45:
        return f"{r.choice(sorted(FUNCTIONS))}({formula(r, depth - 1)})"
    op = r.choice(["+", "-", "*", "/", "**", "^"])
    return f"({formula(r, depth - 1)}{op}{formula(r, depth - 1)})"


class TimedOut(BaseException):  # not an Exception: no handler inside nnphd or SymPy may swallow it
    pass


def _alarm(*_):
    raise TimedOut


def one(law: str) -> str:
    fam = parse_law(law, ["x"])
    q, v, t = np.random.rand(50, 1), np.random.rand(50, 1), np.random.rand(50)
    th = [1.0] * len(fam.nl_names)
    with np.errstate(all="ignore"):
        fam.basis(np, th, q, v, t)
        if fam.fixed is not None:
            fam.fixed(np, th, q, v, t)
    fam.symbols([1.3] * len(fam.nl_names), [sp.Symbol("x")], [sp.Symbol("x_dot")], sp.Symbol("t"))
    return "law"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=8)
    ap.add_argument("--n", type=int, default=1500)
    ap.add_argument("--timeout", type=int, default=10)
    a = ap.parse_args()
    resource.setrlimit(resource.RLIMIT_AS, (6 * 2**30, 6 * 2**30))
    warnings.simplefilter("error", np.exceptions.ComplexWarning)  # a complex value cast to real is a defect
    signal.signal(signal.SIGALRM, _alarm)
    r, rows = random.Random(a.seed), []
    for _ in range(a.n):
        law = f"c*x_dot + {formula(r, r.randint(1, 7))}"
        t0 = time.perf_counter()
        signal.alarm(a.timeout)
        try:
            how = one(law)
        except ValueError:
            how = "ValueError"
        except TimedOut:
            how = "TIMEOUT"
        except Exception as e:  # noqa: BLE001 — reported: a defect
            how = f"{type(e).__name__}: {str(e)[:80]}"
        finally:
            signal.alarm(0)
        rows.append((time.perf_counter() - t0, how, law))
    rows.sort(reverse=True)
    print(f"{a.n} formulas (seed {a.seed}): {dict(Counter(h for _, h, _ in rows))}")
    print("slowest:")
    for dt, how, law in rows[:5]:
        print(f"  {dt:6.2f} s  {how:10s}  {law[:110]}")
    bad = [(how, law) for _, how, law in rows if how not in ("law", "ValueError")]
    for how, law in bad:
        print(f"DEFECT {how}: {law}")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
