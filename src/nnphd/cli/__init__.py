"""Command line: ``nnphd systems``, ``sweep``, ``discover``, ``predict``, ``study``, ``reproduce``, ``detect``,
``demo`` (the commands in :mod:`nnphd.cli.paper` and :mod:`nnphd.cli.detect`, shared pieces in
:mod:`nnphd.cli.common`).

Bad input gives a one-line ``error: ...`` on stderr and exit code 2, with nothing written.
"""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from nnphd.cli import detect as _detect  # noqa: F401  (registers the command)
from nnphd.cli import paper as _paper  # noqa: F401  (registers the commands)
from nnphd.cli.common import InputError, _ClickException, app


def main(argv: list[str] | None = None) -> int:
    from nnphd import configure
    from nnphd._extras import MissingExtra

    configure()  # the command line owns its process: float64 and the fast XLA:CPU setting
    cmd = typer.main.get_command(app)
    args = list(argv if argv is not None else sys.argv[1:])
    out_before = _out_state(args)
    try:
        rc = cmd.main(args=args, prog_name="nnphd", standalone_mode=False)
        if rc == 130:  # typer returns (does not raise) the exit code of an interrupt (Ctrl-C)
            return _interrupted(args, out_before)
        if isinstance(rc, int) and rc:
            return rc
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except MissingExtra as e:  # an optional dependency of the command is not installed
        print(f"error: {e}", file=sys.stderr)
        return 2
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
    return 0


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
    if d is not None and d.is_dir():
        left = list(d.iterdir())
        if not left and out_existed is False:
            d.rmdir()
        elif any(f.name == ".checkpoint.npz" for f in left):
            msg += f"; the finished steps are kept in {d}: run the same command again to resume"
    print(msg, file=sys.stderr)
    return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())


def entry() -> None:  # console-script entry point
    sys.exit(main())
