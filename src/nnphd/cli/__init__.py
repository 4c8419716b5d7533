"""Command line: ``nnphd systems``, ``sweep``, ``discover``, ``predict``, ``study``, ``reproduce``, ``detect``,
``demo`` (the commands in :mod:`nnphd.cli.paper` and :mod:`nnphd.cli.detect`, shared pieces in
:mod:`nnphd.cli.common`).

Bad input gives a one-line ``error: ...`` on stderr and exit code 2, with nothing written; an interrupt exits 130.
A run that fails or is interrupted leaves no result file at the top of its ``--out`` folder and removes every folder
it created and left empty (the given or default ``--out`` and its parents; never one that existed before), see
:func:`nnphd.cli.common.undo_run`; a defect of nnphd gives one ``error: internal error ...`` line and
exit code 1 (``NNPHD_TRACEBACK=1`` shows the traceback).  Each command claims its ``--out`` folder
(:func:`nnphd.io.outdir.claim_out_dir`): a second run into the same folder is refused while the first runs.

Nothing a file, a column or an argument names reaches the terminal raw: every line printed here, every Rich text
(:func:`nnphd.io.escape.rich`) and every warning shown while a command runs goes through
:func:`nnphd.io.escape.terminal`, which shows control and bidi characters as escapes (``\\x1b``, ``\\u202e``).
"""

from __future__ import annotations

import os
import sys
import warnings

import typer

from nnphd.cli import detect as _detect  # noqa: F401  (registers the command)
from nnphd.cli import paper as _paper  # noqa: F401  (registers the commands)
from nnphd.cli.common import ClickError, InputError, app, begin_run, claimed_outs, undo_run
from nnphd.io.errors import DataError
from nnphd.io.escape import one_line, terminal
from nnphd.io.outdir import release_out_dirs
from nnphd.parallel import SchedulerError, UnitsFailed


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``argv`` (default: ``sys.argv[1:]``); returns the exit code."""
    shown_warning = warnings.formatwarning
    warnings.formatwarning = _escaped_warnings(shown_warning)  # a warning's message is shown escaped too
    try:
        return _main(argv)
    finally:
        warnings.formatwarning = shown_warning


def _main(argv: list[str] | None) -> int:
    from nnphd import configure
    from nnphd._extras import MissingExtra

    # the command line owns its process: float64, the fast XLA:CPU setting, and compiled programs cached on disk
    # (~/.cache/nnphd/jax; NNPHD_COMPILE_CACHE=folder or 0 for off), so a second run does not compile them again
    configure(compile_cache=True)
    cmd = typer.main.get_command(app)
    args = list(argv if argv is not None else sys.argv[1:])
    begin_run()
    try:
        rc = cmd.main(args=args, prog_name="nnphd", standalone_mode=False)
        if rc == 130:  # typer returns (does not raise) the exit code of an interrupt (Ctrl-C)
            return _interrupted()
        if isinstance(rc, int) and rc:
            return rc
    except (InputError, DataError, MissingExtra, SchedulerError) as e:  # bad input (also found mid-run), a missing
        return _failed(str(e), 2)  # optional extra, a --scheduler that does not answer
    except typer.Exit as e:
        return getattr(e, "exit_code", 0)
    except (typer.Abort, KeyboardInterrupt):
        return _interrupted()
    except ClickError as e:
        if type(e).__name__ == "NoArgsIsHelpError":  # bare `nnphd`: show help
            ctx = getattr(e, "ctx", None)
            print(ctx.get_help() if ctx is not None else e.format_message())
            return 2
        return _failed(e.format_message(), getattr(e, "exit_code", 2) or 2)
    except UnitsFailed as e:  # independent units failed (reported, the others cached): not bad input, not a defect
        return _failed(str(e), 1)
    except MemoryError:
        return _failed("out of memory; use a smaller file (fewer rows) or fewer --steps", 1)
    except Exception as e:  # a defect of nnphd: one line and exit 1; NNPHD_TRACEBACK=1 shows the traceback
        if os.environ.get("NNPHD_TRACEBACK"):
            undo_run()
            raise
        msg = f"internal error ({type(e).__name__}: {_one_line(e)}); please report it, with NNPHD_TRACEBACK=1 output"
        return _failed(msg, 1)
    finally:
        release_out_dirs()
    return 0


def _escaped_warnings(format_warning):
    """``warnings.formatwarning`` showing the message's control and bidi characters as escapes (a warning may quote
    a file or column name); the location and source line are nnphd's or a library's code, shown as they are."""

    def shown(message, category, filename, lineno, line=None) -> str:
        return format_warning(terminal(message), category, filename, lineno, line)

    return shown


def _one_line(e: BaseException | str) -> str:
    """The text of ``e`` as one line of at most 300 characters (before escaping), control and bidi characters shown
    as escapes (:func:`nnphd.io.escape.one_line`)."""
    return one_line(e, 300)


def _failed(message: str, code: int) -> int:
    """One ``error: ...`` line (control and bidi characters of the names it quotes shown as escapes) and ``code``;
    what the run created and left empty is removed (:func:`undo_run`)."""
    undo_run()
    print(f"error: {_one_line(message)}", file=sys.stderr)
    return code


def _interrupted() -> int:
    """Ctrl-C: exit 130 with one line; what the run created and left empty is removed (:func:`undo_run`); a kept
    checkpoint is named (the same command resumes from it)."""
    undo_run()
    msg = "error: interrupted"
    for d in claimed_outs():
        try:
            if d.is_dir() and any(f.name == ".checkpoint.npz" for f in d.iterdir()):
                msg += f"; the finished steps are kept in {terminal(d)}: run the same command again to resume"
                break
        except OSError:
            pass
    print(msg, file=sys.stderr)
    return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())


def entry() -> None:  # console-script entry point
    sys.exit(main())
