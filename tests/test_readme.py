"""The README's commands are real: every ``nnphd …`` line of its bash blocks (and of docs/guide.md's) is parsed by
the command line itself — the sub-command exists, every option exists and its value is valid — without running it
(the paper-scale ones take minutes; the Python quickstart is run whole by tests/test_api.py). The README stays a
five-minute read."""

from __future__ import annotations

import os
import re
import shlex

import pytest
import typer

from nnphd.cli import app

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _commands(doc: str) -> list[str]:
    text = open(os.path.join(ROOT, doc), encoding="utf-8").read()
    lines = [ln.split("  #")[0].strip() for b in re.findall(r"```bash\n(.*?)```", text, re.S) for ln in b.splitlines()]
    return [ln for ln in lines if ln.startswith("nnphd ")]


def _parse(line: str):
    """(the sub-command's name, its parsed parameters) as the CLI would see ``line``; click's error if it would not."""
    cmd = typer.main.get_command(app)
    ctx = cmd.make_context("nnphd", shlex.split(line)[1:])
    c, rest = cmd, [*ctx._protected_args, *ctx.args]
    while hasattr(c, "resolve_command"):  # a group: descend to the sub-command
        name, c, rest = c.resolve_command(ctx, rest)
        ctx = c.make_context(name, rest, parent=ctx)
        rest = [*getattr(ctx, "_protected_args", []), *ctx.args]
    assert rest == [], f"{line}: left unparsed: {rest}"
    return c.name, ctx.params


@pytest.mark.parametrize("line", _commands("README.md") + _commands("docs/guide.md"))
def test_every_command_in_the_docs_is_one_the_cli_takes(line):
    name, params = _parse(line)
    assert name == shlex.split(line)[1 + (shlex.split(line)[1] in ("study", "demo"))]


def test_the_parse_reads_values_and_fails_on_what_the_cli_would_refuse():
    name, p = _parse("nnphd detect data.csv --steps 300 --n-seeds 1 --law-fit pointwise --field uniform")
    assert name == "detect" and p["steps"] == 300 and p["n_seeds"] == 1 and p["files"] == ["data.csv"]
    assert p["law_fit"].value == "pointwise" and p["field"].value == "uniform"
    assert _parse("nnphd detect data.csv --repeats 3")[1]["n_seeds"] == 3  # the old name of --n-seeds
    for bad in ("nnphd detect data.csv --no-such-option", "nnphd detect data.csv --steps 2", "nnphd sweepp"):
        with pytest.raises(Exception) as e:
            _parse(bad)
        assert type(e.value).__name__ in ("NoSuchOption", "BadParameter", "UsageError"), e.value


def test_the_readme_is_a_five_minute_read():
    lines = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read().splitlines()
    assert len(lines) <= 150
    assert lines[0].startswith("# nnphd")


def _json(name):
    import json

    with open(os.path.join(ROOT, "benchmarks", "results", name)) as f:
        return json.load(f)


def test_the_readmes_time_and_scale_out_numbers_are_those_of_the_json():
    import statistics

    text = " ".join(open(os.path.join(ROOT, "README.md"), encoding="utf-8").read().split())
    m = re.search(r"takes (\d+)–(\d+) s a file warm \(median (\d+);", text)
    warm = [r["warm"]["total_s"] for r in _json("stage_times.json")]
    assert m and [int(x) for x in m.groups()] == [round(min(warm)), round(max(warm)), round(statistics.median(warm))]
    m = re.search(r"a batch of (\d+) files simulated on (\d+) workers at efficiency (\d\.\d+)", text)
    sets = _json("cluster_scaling.json")["sets"]
    batch = next(s for k, s in sets.items() if k.endswith(f"= {m.group(1)} files"))
    row = next(r for r in batch["rows"] if r["workers"] == int(m.group(2)))
    assert f"{row['efficiency']:.2f}" == m.group(3)
