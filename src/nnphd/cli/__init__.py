"""Command line: ``nnphd systems``, ``sweep``, ``discover``, ``predict``, ``study``, ``reproduce``, ``detect``,
``demo`` (the commands in :mod:`nnphd.cli.paper` and :mod:`nnphd.cli.detect`, shared pieces in
:mod:`nnphd.cli.common`).

Bad input gives a one-line ``error: ...`` on stderr and exit code 2, with nothing written (an ``--out`` folder the run
created is removed again); an interrupt exits 130; a defect of nnphd gives one ``error: internal error ...`` line and
exit code 1 (``NNPHD_TRACEBACK=1`` shows the traceback).  Each command claims its ``--out`` folder
(:func:`nnphd.io.outdir.claim_out_dir`): a second run into the same folder is refused while the first runs.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import typer

from nnphd.cli import detect as _detect  # noqa: F401  (registers the command)
from nnphd.cli import paper as _paper  # noqa: F401  (registers the commands)
from nnphd.cli.common import InputError, _ClickException, app
from nnphd.io.errors import DataError
from nnphd.io.outdir import release_out_dirs
from nnphd.parallel import UnitsFailed


def main(argv: list[str] | None = None) -> int:
    from nnphd import configure
    from nnphd._extras import MissingExtra

    # the command line owns its process: float64, the fast XLA:CPU setting, and compiled programs cached on disk
    # (~/.cache/nnphd/jax; NNPHD_COMPILE_CACHE=folder or 0 for off), so a second run does not compile them again
    configure(compile_cache=True)
    cmd = typer.main.get_command(app)
    args = list(argv if argv is not None else sys.argv[1:])
    out_before = _out_state(args)
    try:
        rc = cmd.main(args=args, prog_name="nnphd", standalone_mode=False)
        if rc == 130:  # typer returns (does not raise) the exit code of an interrupt (Ctrl-C)
            return _interrupted(args, out_before)
        if isinstance(rc, int) and rc:
            return rc
    except (InputError, DataError, MissingExtra) as e:  # bad input (also found mid-run), a missing optional extra
        return _failed(args, out_before, str(e), 2)
    except typer.Exit as e:
        return getattr(e, "exit_code", 0)
    except (typer.Abort, KeyboardInterrupt):
        return _interrupted(args, out_before)
    except _ClickException as e:
        if type(e).__name__ == "NoArgsIsHelpError":  # bare `nnphd`: show help
            ctx = getattr(e, "ctx", None)
            print(ctx.get_help() if ctx is not None else e.format_message())
            return 2
        print(f"error: {e.format_message()}", file=sys.stderr)
        return getattr(e, "exit_code", 2) or 2
    except UnitsFailed as e:  # independent units failed (reported, the others cached): not bad input, not a defect
        return _failed(args, out_before, str(e), 1)
    except MemoryError:
        return _failed(args, out_before, "out of memory; use a smaller file (fewer rows) or fewer --steps", 1)
    except Exception as e:  # a defect of nnphd: one line and exit 1; NNPHD_TRACEBACK=1 shows the traceback
        if os.environ.get("NNPHD_TRACEBACK"):
            raise
        msg = f"internal error ({type(e).__name__}: {_one_line(e)}); please report it, with NNPHD_TRACEBACK=1 output"
        return _failed(args, out_before, msg, 1)
    finally:
        release_out_dirs()
    return 0


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return text[:300] + ("…" if len(text) > 300 else "")


def _failed(args: list[str], out_existed: bool | None, message: str, code: int) -> int:
    """One ``error: ...`` line and ``code``; an --out folder this run created and left empty is removed."""
    _remove_if_created_and_empty(args, out_existed)
    print(f"error: {_one_line(message)}", file=sys.stderr)
    return code


def _out_dir(args: list[str]) -> Path | None:
    if "--out" in args and args.index("--out") + 1 < len(args):
        return Path(args[args.index("--out") + 1])
    eq = [a.split("=", 1)[1] for a in args if a.startswith("--out=")]
    return Path(eq[-1]) if eq else None


def _out_state(args: list[str]) -> bool | None:
    """Whether the --out folder existed before the run (None: no --out given)."""
    d = _out_dir(args)
    return None if d is None or not str(d).strip() else d.exists()


def _interrupted(args: list[str], out_existed: bool | None) -> int:
    """Ctrl-C: exit 130 with one line; an --out folder this run created and left empty is removed; a kept
    checkpoint is named (the same command resumes from it)."""
    d = _out_dir(args)
    msg = "error: interrupted"
    if not _remove_if_created_and_empty(args, out_existed) and d is not None and d.is_dir():
        if any(f.name == ".checkpoint.npz" for f in d.iterdir()):
            msg += f"; the finished steps are kept in {d}: run the same command again to resume"
    print(msg, file=sys.stderr)
    return 130


def _remove_if_created_and_empty(args: list[str], out_existed: bool | None) -> bool:
    d = _out_dir(args)
    if out_existed is False and d is not None and d.is_dir() and not any(d.iterdir()):
        try:
            d.rmdir()
        except OSError:
            return False
        return True
    return False


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())


def entry() -> None:  # console-script entry point
    sys.exit(main())
