"""Optional dependencies: a one-line error naming the extra to install when a feature needs a missing one."""

from __future__ import annotations

import importlib

EXTRAS = {"pysindy": "explain", "pyoperon": "explain", "jplephem": "astro", "de405": "astro"}


class MissingExtra(ImportError):
    """A feature needs an optional dependency that is not installed (the message says which extra to install)."""


def require(module: str, feature: str):
    """Import ``module`` (e.g. "pysindy", "pyoperon.sklearn") or raise :class:`MissingExtra` for ``feature``."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        top = module.split(".")[0]
        extra = EXTRAS.get(top, "all")
        raise MissingExtra(
            f"{feature} needs {top}, which is not installed ({e.__class__.__name__}: {e}); install it "
            f"with: pip install 'nnphd[{extra}]'"
        ) from None
