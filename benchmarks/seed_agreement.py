"""How much the verdict and the law depend on the seed, from the JSON of runs with different seeds (nothing is
re-run): per file, the verdict and the law (family, or the tied families) of each seed, whether they agree, and
whether any seed claims a family that is wrong (look-alikes: the true family; real recordings: > 25 % from the
reference or lacking a term it needs).

    .venv/bin/python benchmarks/seed_agreement.py [--json out.json] [--seeds 0,1,2]

Inputs: results/real_friction.json, real_friction_seed1.json, real_friction_seed2.json (benchmarks/real_friction.py
--seed 0/1/2), results/friction_laws.json, friction_laws_seed1.json, friction_laws_seed2.json
(benchmarks/friction_laws.py --seeds 0/1/2) and results/laws_table.json, laws_table_seed1.json, laws_table_seed2.json
(benchmarks/laws_table.py --seed 0/1/2); a missing file is skipped. The seconds per file of each seed are printed
beside them (as measured by those runs).
"""

from __future__ import annotations

import argparse
import json
import os

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
REAL = {0: "real_friction.json", 1: "real_friction_seed1.json", 2: "real_friction_seed2.json"}
LOOK = {0: "friction_laws.json", 1: "friction_laws_seed1.json", 2: "friction_laws_seed2.json"}
TABLE = {0: "laws_table.json", 1: "laws_table_seed1.json", 2: "laws_table_seed2.json"}


def _load(name: str) -> list[dict]:
    path = os.path.join(HERE, name)
    return json.load(open(path)) if os.path.exists(path) else []


def _families(status: str, keys: list[str]) -> str:
    """The law as compared across seeds: a claimed family, or a tie as the set of its families (sorted: the order
    within a tie only says which one predictions use)."""
    return "/".join(sorted(keys) if status == "tie" else keys)


def _real_view(r: dict) -> tuple[str, str, bool, float]:
    fams = _families(r["law_status"], [x["law"] for x in r["laws"]]) if r["law_status"] in ("claimed", "tie") else "—"
    wrong = r["law_status"] == "claimed" and not r["right"]
    return r["status"], f"{r['law_status']}: {fams}", wrong, r.get("wall_s", float("nan"))


def _look_view(r: dict) -> tuple[str, str, bool, float]:
    if r["law_status"] in ("claimed", "tie"):
        ties = [t if isinstance(t, str) else t.get("law", "?") for t in r.get("ties") or []]
        fams = _families(r["law_status"], [r["winner"], *ties])
    else:
        fams = "—"
    wrong = r["law_status"] == "claimed" and not r["family_right"]
    return r["status"], f"{r['law_status']}: {fams}", wrong, r.get("wall_s", float("nan"))


def _table_view(r: dict) -> tuple[str, str, bool, float]:
    """A law-table case: its verdict, the claimed law's family (the table keeps the claimed law only) and whether it
    is the truth's (``right`` also judges the error, so a claimed law that is not right counts as wrong)."""
    law = f"{r.get('law_status') or 'claimed'}: {r['law']['law']}" if r.get("law") else "—"
    wrong = bool(r.get("law")) and r.get("law_status") in (None, "claimed") and not r["right"]
    return r["status"], law, wrong, r.get("seconds", float("nan"))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default=None)
    ap.add_argument("--seeds", default="0,1,2", help="the seeds to compare (files of other seeds are ignored)")
    a = ap.parse_args()
    use = {int(x) for x in a.seeds.split(",")}
    rows = []
    for kind, files, key, view in (
        ("real", REAL, "file", _real_view),
        ("look-alike", LOOK, "name", _look_view),
        ("law table", TABLE, "case", _table_view),
    ):
        runs = {s: {r[key]: r for r in _load(f)} for s, f in files.items() if s in use}
        runs = {s: v for s, v in runs.items() if v}
        names = sorted(set().union(*(v.keys() for v in runs.values()))) if runs else []
        for n in names:
            per = {s: view(v[n]) for s, v in runs.items() if n in v}
            if len(per) < 2:
                continue
            rows.append(
                {
                    "kind": kind,
                    "file": n,
                    "seeds": sorted(per),
                    "verdicts": [per[s][0] for s in sorted(per)],
                    "laws": [per[s][1] for s in sorted(per)],
                    "verdicts_agree": len({p[0] for p in per.values()}) == 1,
                    "laws_agree": len({p[1] for p in per.values()}) == 1,
                    "wrong_claim_seeds": [s for s in sorted(per) if per[s][2]],
                    "seconds": [round(per[s][3], 1) for s in sorted(per)],
                }
            )
    print("| kind | file | seeds | verdicts | laws | same verdict | same law | seeds with a wrong claim | s per seed |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['kind']} | {r['file']} | {','.join(map(str, r['seeds']))} | {', '.join(r['verdicts'])} | "
            f"{'; '.join(r['laws'])} | {'yes' if r['verdicts_agree'] else 'no'} | {'yes' if r['laws_agree'] else 'no'} "
            f"| {','.join(map(str, r['wrong_claim_seeds'])) or '—'} | {', '.join(f'{x:.0f}' for x in r['seconds'])} |"
        )
    if rows:
        n = len(rows)
        print(
            f"\n{sum(r['verdicts_agree'] for r in rows)}/{n} files with the same verdict on every seed, "
            f"{sum(r['laws_agree'] for r in rows)}/{n} with the same law; "
            f"{sum(bool(r['wrong_claim_seeds']) for r in rows)}/{n} with a wrong claimed family on some seed"
        )
    if a.json:
        tmp = a.json + ".tmp"
        with open(tmp, "w") as f:
            json.dump(rows, f, indent=1)
        os.replace(tmp, a.json)


if __name__ == "__main__":
    main()
