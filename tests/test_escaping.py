"""Names from the user's data (column names, file names, paths) are the user's text wherever nnphd renders them:
matplotlib shows them literally (no mathtext), Rich prints them literally (no markup), summary.csv guards them
against spreadsheet formulas, HTML escapes them; a batch reads only the regular files directly in its folder, never
a symbolic link nor its own output.  No training: the renderers are called directly, detect's training is faked."""

import csv
import io
import json
import types

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from matplotlib.figure import Figure
from rich.console import Console

from nnphd.cli import main
from nnphd.io.escape import csv_cell, mpl, rich
from nnphd.io.html import escape
from nnphd.io.results import plot_sweep
from nnphd.user import report as rp

HOSTILE = ["$\\frac{x$", "$\\undefinedcmd{x}$", "$$", "a\\$b$", "[/x]", "[bold]b[/bold]", "<script>alert(1)</script>"]
SPECIAL = "$\\[]<>&\"'=_^{}%#~:@+- /"
names = st.text(
    alphabet=st.sampled_from(SPECIAL) | st.sampled_from("\\[$") | st.sampled_from("abxyzλ0"), min_size=1, max_size=20
)
FAST = dict(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=30)  # draws every text: an unescaped "$\frac{x$" raises here
    return buf.getvalue()


def _shown(text) -> str:
    """What matplotlib draws for a Text: its string after mathtext's preprocessing, which must be plain text."""
    s, math = text._preprocess_math(text.get_text())
    assert math is False, text.get_text()
    return s


def test_unescaped_mathtext_raises_escaped_draws_literally():
    fig = Figure()
    ax = fig.subplots()
    ax.set_ylabel("$\\frac{x$")
    with pytest.raises(ValueError):
        _png(fig)  # why: the name alone breaks the figure
    ax.set_ylabel(mpl("$\\frac{x$"))
    assert _png(fig).startswith(b"\x89PNG") and _shown(ax.yaxis.label) == "$\\frac{x$"


@settings(max_examples=20, **FAST)
@given(name=names)
def test_mpl_escape_always_draws_the_literal_name(name):
    fig = Figure(figsize=(2, 2))
    ax = fig.subplots()
    ax.set_ylabel(mpl(name))
    ax.set_title(mpl(name) + ": $L_e$")  # beside mathtext, as plot_sweep's legend does
    _png(fig)
    assert _shown(ax.yaxis.label) == name


def _data(coords, n=30, n_traj=2):
    t = np.tile(np.linspace(0, 1, n), n_traj)
    q = np.stack([np.sin(t + j) for j in range(len(coords))], axis=1)
    return types.SimpleNamespace(t=t, q=q, qdd=-q), np.repeat(np.arange(n_traj), n)


def test_report_figures_draw_hostile_names():
    data, traj = _data(HOSTILE)
    fig = rp.fig_data(data, traj, HOSTILE)
    assert _png(fig).startswith(b"\x89PNG")
    assert [_shown(ax.yaxis.label) for ax in fig.axes] == HOSTILE
    few = HOSTILE[:3]
    data, traj = _data(few)
    fig = rp.fig_forces(data, traj, few, data.q, 0.1 * data.q, lam=0.5)
    assert _png(fig).startswith(b"\x89PNG")
    assert [_shown(fig.axes[2 * j].yaxis.label) for j in range(len(few))] == [f"{c}_ddot" for c in few]
    table = [{"lam": lam, "L_e": 1e-3 * lam, "L_e_train": 1e-3, "L_b": 1e-2} for lam in (0.1, 0.5, 2, 10)]
    assert rp.plot_loss(table, 3.0).startswith(b"\x89PNG")
    trend = {
        "block_t": [[1.0, 2.0, 3.0]] * 2,
        "block_dE": [[1.0, 0.5, 0.25]] * 2,
        "rate": 0.7,
        "valid": True,
        "rate_per_period": 0.5,
        "z": 5.0,
    }
    assert rp.plot_energy(trend).startswith(b"\x89PNG")
    fig = plot_sweep({n: table for n in HOSTILE}, "$L_e(\\lambda)$")
    assert _png(fig).startswith(b"\x89PNG")
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()][::2] == [f"{mpl(n)}: $L_e$" for n in HOSTILE]


@settings(max_examples=300, **FAST)
@given(name=names.filter(lambda s: s == s.strip()))  # Rich keeps inner spaces; a line's end is its own business
def test_rich_escape_always_prints_the_literal_name(name):
    con = Console(file=io.StringIO(), width=10_000, emoji=False)
    con.print(f"[bold]v[/] {rich(name)}", highlight=False)
    con.print(f"[yellow]{rich(name)} and[/] [red]x[/]", highlight=False)  # followed by plain text and markup
    assert con.file.getvalue() == f"v {name}\n{name} and x\n"


def test_csv_cell_guards_formulas_keeps_numbers():
    for s in ('=HYPERLINK("http://x")', "+1", "-a", "@SUM(A1)", "\tx", "\rx"):
        assert csv_cell(s) == "'" + s
    assert csv_cell("a=b") == "a=b" and csv_cell(None) == "" and csv_cell(True) == "True"
    assert csv_cell(-1.5) == -1.5 and csv_cell(-2) == -2  # a negative number is a number, not text


def _csv(path, header, n=40):
    t = np.arange(n) * 0.1
    path.write_text(header + "\n" + "".join(f"{ti},{np.cos(ti)},{-np.sin(ti)}\n" for ti in t))
    return path


def _fake_report(coords):
    c = coords[0]
    formula = {f"{c}_ddot": f"-k*{c}_dot"}
    return {
        "status": "detected",
        "new_physics": True,
        "confidence": 0.9,
        "effect": f"friction on [/x] {c}",
        "warnings": [f"{c}: noisy [/warn]"],
        "angle_suggestions": [[c, "wraps at [/pi]"]],
        "reasons": [f"f_n of {c} is [red]large[/red]"],
        "formula": None,
        "blind": False,
        "law": {"law": {"title": "[/title] linear", "formula": formula, "params": {"k": 0.5}, "stderr": {"k": 0.1}}},
        "wall_time_s": 1.0,
    }


def test_detect_cli_prints_hostile_names_literally(tmp_path, capsys, monkeypatch):
    """A column "[/x]" and an --out holding Rich markup: the verdict, the law and the paths print literally (an
    unescaped "[/x]" raised rich's MarkupError: an internal error after the training)."""
    import nnphd.cli.common as common
    import nnphd.user.detect as ud

    monkeypatch.setattr(common.console, "width", 10_000)
    seen = {}

    def fake_detect_data(data, out=None, progress=None, **kw):
        seen["coords"] = data.coords
        progress(0, 1, f"training {data.coords[0]} [/progress]")
        return types.SimpleNamespace(report=_fake_report(data.coords)), None  # the CLI prints the result's report

    monkeypatch.setattr(ud, "detect_data", fake_detect_data)
    path = _csv(tmp_path / "d.csv", 't,"[/x]",$\\frac{v$')
    out = tmp_path / "o[bold]ut[/x]"
    rc = main(["detect", str(path), "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0 and seen["coords"] == ("[/x]", "$\\frac{v$")
    for s in (
        "DETECTED",
        "effect: friction on [/x] [/x]",
        "warning: [/x]: noisy [/warn]",
        "note: '[/x]' looks like an angle (wraps at [/pi])",
        "f_n of [/x] is [red]large[/red]",
        "law: [/title] linear: [/x]_ddot = -k*[/x]_dot",
        f"wrote {out}/report.json",
    ):
        assert s in text, (s, text)


def test_batch_summary_guards_csv_escapes_html_skips_links_and_its_out(tmp_path, capsys, monkeypatch):
    """A file "=HYPERLINK(…).csv": its cells in summary.csv start with "'"; a symbolic link in the folder (here to a
    "private key" outside it) is not followed but listed as skipped; names are HTML-escaped; --out the input folder
    is refused, a subfolder of it is fine, and files inside --out are never read."""
    import nnphd.cli.common as common
    import nnphd.user.batch as batch
    from nnphd.parallel import Outcome

    monkeypatch.setattr(common.console, "width", 10_000)
    read = []

    def fake_run_units(units, workers, scheduler, progress=None):  # no training: a row per file, one error
        res = {}
        for u in units:
            read.append(u.kwargs["path"])
            progress(0, 1, f"{u.kwargs['path']}: running")
            rep = {"status": "none", "confidence": 0.8, "effect": "-0.5%/period", "formula": None, "law": None}
            if "bad" in u.key:
                res[u.key] = Outcome(u.key, False, error="-DataError: <script>alert(1)</script> [/x]")
            else:
                res[u.key] = Outcome(u.key, True, batch.summary_row(u.key, u.kwargs["path"], rep, False))
        return res

    monkeypatch.setattr(batch, "run_units", fake_run_units)
    d = tmp_path / "data"
    d.mkdir()
    _csv(d / '=HYPERLINK("evil").csv', "t,x,y")
    _csv(d / "<img src=x onerror=alert(1)>[bold]bad.csv", "t,x,y")
    key = tmp_path / "id_rsa.csv"
    key.write_text("-----BEGIN PRIVATE KEY-----\nsecret\n")
    (d / "key.csv").symlink_to(key)
    monkeypatch.chdir(d)  # the folder as "." gives bare file names, as a user typing `nnphd detect .` gets
    out = tmp_path / "out"

    rc = main(["detect", ".", "--out", str(out), "--workers", "1"])
    text = capsys.readouterr().out
    assert rc == 1  # the "bad" file failed
    assert sorted(read) == ["<img src=x onerror=alert(1)>[bold]bad.csv", '=HYPERLINK("evil").csv']  # no link read
    with open(out / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    by = {r["file"]: r for r in rows}
    assert set(by) == {'\'=HYPERLINK("evil").csv', "<img src=x onerror=alert(1)>[bold]bad.csv", "key.csv"}
    assert by['\'=HYPERLINK("evil").csv']["effect"] == "'-0.5%/period"
    assert by['\'=HYPERLINK("evil").csv']["confidence"] == "0.8"  # a number stays a number
    assert by["<img src=x onerror=alert(1)>[bold]bad.csv"]["error"].startswith("'-DataError")
    assert by["key.csv"]["status"] == "skipped" and by["key.csv"]["error"] == "symbolic link, not followed"
    assert "PRIVATE" not in (out / "summary.csv").read_text() + (out / "summary.html").read_text()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["skipped"] == [{"file": "key.csv", "reason": "symbolic link, not followed"}]
    html = (out / "summary.html").read_text()
    assert "<script>" not in html and "<img" not in html and escape("<script>alert(1)</script>") in html
    assert escape("<img src=x onerror=alert(1)>[bold]bad.csv") in html
    assert "symbolic link, not followed" in html
    for shown in ("[/x]", '=HYPERLINK("evil").csv', "<img src=x onerror=alert(1)>[bold]bad.csv", "key.csv"):
        assert shown in text, (shown, text)
    assert "symbolic link, not followed" in text

    # --out the input folder: refused before anything is written (its summary.csv would be data on a rerun)
    rc = main(["detect", ".", "--out", "."])
    err = capsys.readouterr().err
    assert rc == 2 and "the input folder is the --out folder" in err and len(err.strip().splitlines()) == 1
    assert not (d / "summary.csv").exists()
    # --out a subfolder of the input folder: fine, and a rerun does not read its summary.csv (not recursive)
    for _ in range(2):
        read.clear()
        assert main(["detect", ".", "--out", "nnphd", "--workers", "1"]) == 1
        assert sorted(read) == ["<img src=x onerror=alert(1)>[bold]bad.csv", '=HYPERLINK("evil").csv']
    assert (d / "nnphd" / "summary.csv").is_file()
    # files given one by one that lie inside --out (a shell glob over it) are skipped, never read
    bad = d / "<img src=x onerror=alert(1)>[bold]bad.csv"
    files, skipped = batch.scan_paths([out / "summary.csv", bad, d / "key.csv"], out)
    assert files == [bad]  # a link named on the command line is skipped as in a folder
    assert skipped == [
        {"file": str(d / "key.csv"), "reason": "symbolic link, not followed"},
        {"file": str(out / "summary.csv"), "reason": "inside the --out folder (nnphd's own output), not read"},
    ]


def test_html_report_escapes_names():
    """report.html of a file whose column is "<script>alert(1)</script>": escaped in every place it shows."""
    name = "<script>alert(1)</script>"
    rep = {
        "file": f"/data/{name}.csv",
        "status": "none",
        "effect": None,
        "confidence": 0.5,
        "confidence_basis": name,
        "reasons": [name],
        "warnings": [name],
        "angle_suggestions": [[name, name]],
        "checks": {"naive": {"ratio": []}, "note": name},
        "evidence": {"energy_trend": {"valid": False, "reason": name}, "shooting": {"valid": False, "reason": name}},
        "table": [],
        "noise": {
            name: {
                "noise": 0.1,
                "noise_relative": 0.01,
                "qd": {"source": name, "relative_error": 0.1},
                "qdd": {"source": name, "relative_error": None},
            }
        },
        "formula": {"formula": {f"{name}_ddot": name}, "method": name},
        "law": {"reason": name, "candidates": []},
        "quality": {"samples_per_period": 20.0, "usable": True, "pointwise_ok": False, "reason": name},
        "angles": [name],
        "data": {"n_traj": 1, "n_rows": 10},
        "blind": False,
        "settings": {"x": name},
    }
    html = rp.render_html(rep, {f"{name}.png": b"\x89PNG"})
    assert "<script>" not in html and html.count(escape(name)) >= 15
