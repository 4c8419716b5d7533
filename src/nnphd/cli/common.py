"""The command line's shared pieces: the typer apps, the console, the one progress bar, the choice enums and
input parsing (bad input: a one-line ``error: ...`` on stderr, exit code 2, nothing written)."""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import os
import typing
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from nnphd.io.limits import MAX_N_SEEDS, MAX_SEED, MAX_SR_TIME, MAX_STEPS  # noqa: F401  (the options' ranges)

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
    help="nnphd — Neural New-Physics Detector: find the non-conservative part of a force field.",
)
console = Console(emoji=False)  # ":name:" in a column or file name stays literal (markup: nnphd.io.escape.rich)


def options_command(options: type):
    """A typer command whose options are the fields of the frozen dataclass ``options``: each field's default is its
    ``typer.Argument`` or ``typer.Option``, and the decorated function receives them as one ``options`` record (typer
    reads the signature made here, one parameter per field). The record is built by typer only: its class defaults
    are option declarations, not values."""
    hints = typing.get_type_hints(options)
    kind = inspect.Parameter.POSITIONAL_OR_KEYWORD
    params = [inspect.Parameter(f.name, kind, default=f.default, annotation=hints[f.name]) for f in dataclasses.fields(options)]  # fmt: skip

    def decorate(fn):
        @functools.wraps(fn)
        def command(**given):
            return fn(options(**given))

        command.__signature__ = inspect.Signature(params)
        command.__annotations__ = {p.name: p.annotation for p in params}
        return command

    return decorate


def _version(value: bool) -> None:
    if value:
        from nnphd import __version__

        print(f"nnphd {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", "-V", is_eager=True, callback=_version, help="print the version and exit"
    ),
) -> None:
    """nnphd — Neural New-Physics Detector: find the non-conservative part of a force field."""


# typer ≥ 0.2x vendors click; find its exception base classes through the public BadParameter's MRO.
ClickError = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")


@contextmanager
def progress_bar(title: str):
    """The CLI's side of the one progress interface: a rich bar fed by ``progress(done, total, message)`` (the title
    and messages may quote file or column names: shown literally: Rich markup escaped, control and bidi
    characters shown as escapes, :func:`nnphd.io.escape.rich`)."""
    from nnphd.io.escape import rich as _r

    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=False,
    ) as prog:
        task = prog.add_task(_r(title), total=None)
        yield lambda done, total, message: prog.update(task, completed=done, total=total, description=_r(message))


class SweepMode(StrEnum):
    warm = "warm"
    vmap = "vmap"
    scratch = "scratch"
    fast = "fast"


class Precision(StrEnum):  # nnphd.engine.models.ModelConfig.dtype
    float64 = "float64"
    float32 = "float32"


DTYPE_HELP = "precision of the training: float64 (default) or float32 (faster on a GPU; less margin in the numbers)"


class DiscoverySystem(StrEnum):  # nnphd.paper.discover.DISCOVERY_SYSTEMS (a test keeps them equal)
    double_pendulum = "double-pendulum"
    neptune = "neptune"
    gw = "gw"


class LawLevel(StrEnum):
    auto = "auto"
    pointwise = "pointwise"
    trajectory = "trajectory"


class Field(StrEnum):
    learned = "learned"
    uniform = "uniform"
    vertical = "vertical"


class Trim(StrEnum):
    auto = "auto"
    yes = "yes"
    no = "no"


def workers_option():
    return typer.Option(
        None,
        "--workers",
        min=1,
        max=4096,
        help="local Dask worker processes, one XLA thread each (default: one per core, and a single file's seeds on one thread per core of this process; 1: all in this process, one after another)",
    )


def _check_scheduler(value: str | None) -> str | None:
    """--scheduler: its form, and NNPHD_SCHEDULER_TIMEOUT (:func:`nnphd.parallel.connect_timeout`), are checked when
    the command line is read, before anything is written or contacted."""
    if value is None:
        return None
    from nnphd.parallel import check_scheduler_address, connect_timeout

    try:
        connect_timeout()
        return check_scheduler_address(value)
    except ValueError as e:
        raise InputError(str(e)) from None


def scheduler_option():
    from nnphd.parallel import CONNECT_TIMEOUT_S

    return typer.Option(
        None,
        "--scheduler",
        callback=_check_scheduler,
        help="address of an existing Dask scheduler (e.g. tcp://host:8786) instead of local workers; it must answer "
        f"within {CONNECT_TIMEOUT_S:g} s (NNPHD_SCHEDULER_TIMEOUT=seconds)",
    )


class InputError(Exception):
    """Bad user input: reported as one line, exit code 2."""


MAX_P = 10  # nnphd.engine.train.MAX_P, the largest loss index (why: there); a test keeps them equal
P_HELP = f"the loss norm: index p of the L_p loss, 1 ≤ p ≤ {MAX_P} (paper: 1; larger p overflow float64), or 'mse'"


def parse_loss_p(value):
    """A loss index as :func:`nnphd.engine.train.parse_p` (1 ≤ p ≤ MAX_P, or 'mse'); InputError if not."""
    from nnphd.engine.train import parse_p

    try:
        return parse_p(value)
    except ValueError as e:
        raise InputError(str(e)) from None


# ---- what a run created: removed again if it fails or is interrupted (nnphd.cli.main) -------------------------------
RESULT_FILES = ("results.json", "summary.json", "report.json", "table2.json")
_run = {"created": [], "outs": []}


def begin_run() -> None:
    """Forget the folders and files of an earlier run in this process (nnphd.cli.main calls it before each
    command)."""
    from nnphd.io.results import forget_written

    forget_written()
    _run.update(created=[], outs=[])


def claim_out(path):
    """:func:`nnphd.io.outdir.claim_out_dir`, first noting which folders of ``path`` do not exist yet (the run
    creates them): :func:`undo_run` removes those it leaves empty, if the run fails or is interrupted."""
    from nnphd.io.outdir import claim_out_dir

    if str(path).strip():
        full = Path(os.path.join(os.getcwd(), os.fspath(path)))  # lexical: no symlink is followed
        for d in (full, *full.parents):
            if d.name in ("", ".", ".."):  # "a/.." names a folder that exists (or will) under another name
                continue
            if os.path.lexists(d):
                break
            if d not in _run["created"]:
                _run["created"].append(d)
    p = claim_out_dir(path)
    _run["outs"].append(Path(path))
    return p


def claimed_outs() -> list[Path]:
    """The --out folders this run claimed, as given."""
    return list(_run["outs"])


def undo_run() -> None:
    """After a failed or interrupted run: remove the result files (:data:`RESULT_FILES`) this process wrote at the
    top of its --out folders (a failed run leaves no result behind; caches and checkpoints stay, for a rerun to
    resume), then every folder it created and left empty, innermost first. A file counts as written by the run only
    while it is the very file the run wrote (:func:`nnphd.io.results.written_by_this_process`: same device and
    inode), not by its modification time: a file that was there before, or was put there since, is never removed;
    nor is a folder that existed before."""
    from nnphd.io.results import written_by_this_process

    for out in _run["outs"]:
        for name in RESULT_FILES:
            f = out / name
            try:
                if written_by_this_process(f):
                    f.unlink()
            except OSError:
                pass
    for d in sorted(_run["created"], key=lambda d: -len(d.parts)):  # innermost first
        try:
            if d.is_dir() and not d.is_symlink() and not any(d.iterdir()):
                d.rmdir()
        except OSError:
            pass


# --lambdas: at most this many λ (the paper's grid has 13; each λ is a whole training run, and a λ list of thousands
# only makes a run that never ends)
MAX_LAMBDAS = 64


def parse_lambdas(value: str | None):
    """``--lambdas`` as a tuple of floats (None: the paper's grid, :data:`nnphd.engine.train.PAPER_LAMBDAS`): at most
    :data:`MAX_LAMBDAS` comma-separated distinct finite numbers > 0, some below and some above 1; an
    :class:`InputError` (one line) if not. The count is checked before any value is read."""
    from nnphd.engine.train import PAPER_LAMBDAS

    if value is None:
        return PAPER_LAMBDAS
    toks = value.split(",")
    if len(toks) > MAX_LAMBDAS:
        raise InputError(f"--lambdas takes at most {MAX_LAMBDAS} values (the paper's grid has 13), got {len(toks)}")
    out = []
    for tok in toks:
        try:
            x = float(tok)
        except ValueError:
            raise InputError(f"--lambdas must be comma-separated numbers > 0, got {tok.strip()!r}") from None
        if not math.isfinite(x) or x <= 0:
            raise InputError(f"λ must be > 0, got {tok.strip()}")
        out.append(x)
    if len(set(out)) != len(out):
        raise InputError(f"--lambdas: λ values must be distinct, got {value}")
    if not any(x < 1 for x in out) or not any(x > 1 for x in out):
        raise InputError("--lambdas must contain values both below and above 1 (the transition is read across λ=1)")
    return tuple(out)


# ---- nnphd study: the paper's λ/p study (Fig. 5) and data-quality study (Fig. 6) ----------------------------------
study_app = typer.Typer(
    no_args_is_help=True, help="Paper studies: λ and loss dependence (Fig. 5), data quality (Fig. 6)."
)
app.add_typer(study_app, name="study")


def parse_csv(name: str, value: str | None, conv, default):
    if value is None:
        return default
    toks = [t.strip() for t in value.split(",")]
    if not all(toks):
        raise InputError(f"{name} must be a comma-separated list, got {value!r}")
    return tuple(conv(t) for t in toks)


def fraction_option(name: str):
    def conv(tok: str) -> float:
        try:
            x = float(tok)
        except ValueError:
            raise InputError(f"{name} must be comma-separated numbers in [0, 1], got {tok!r}") from None
        if not (0.0 <= x <= 1.0):
            raise InputError(f"{name} must be comma-separated numbers in [0, 1], got {tok!r}")
        return x

    return conv


demo_app = typer.Typer(no_args_is_help=True, help="Demonstrations on real data.")
app.add_typer(demo_app, name="demo")
