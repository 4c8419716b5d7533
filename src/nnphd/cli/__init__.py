"""Command line: ``nnphd systems``, ``sweep``, ``discover``, ``predict``, ``study``, ``reproduce``, ``detect``,
``demo`` (the commands in :mod:`nnphd.cli.paper` and :mod:`nnphd.cli.detect`, shared pieces in
:mod:`nnphd.cli.common`).

Bad input gives a one-line ``error: ...`` on stderr and exit code 2, with nothing written.
"""

from __future__ import annotations

import sys

import typer

from nnphd.cli import detect as _detect  # noqa: F401  (registers the command)
from nnphd.cli import paper as _paper  # noqa: F401  (registers the commands)
from nnphd.cli.common import InputError, _ClickException, app


def main(argv: list[str] | None = None) -> int:
    from nnphd import configure
    from nnphd._extras import MissingExtra

    configure()  # the command line owns its process: float64 and the fast XLA:CPU setting
    cmd = typer.main.get_command(app)
    try:
        cmd.main(args=argv if argv is not None else sys.argv[1:], prog_name="nnphd", standalone_mode=False)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except MissingExtra as e:  # an optional dependency of the command is not installed
        print(f"error: {e}", file=sys.stderr)
        return 2
    except typer.Exit as e:
        return getattr(e, "exit_code", 0)
    except typer.Abort:
        print("error: aborted", file=sys.stderr)
        return 130
    except _ClickException as e:
        if type(e).__name__ == "NoArgsIsHelpError":  # bare `nnphd`: show help
            ctx = getattr(e, "ctx", None)
            print(ctx.get_help() if ctx is not None else e.format_message())
            return 2
        print(f"error: {e.format_message()}", file=sys.stderr)
        return getattr(e, "exit_code", 2) or 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())


def entry() -> None:  # console-script entry point
    sys.exit(main())
