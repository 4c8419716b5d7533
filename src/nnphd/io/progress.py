"""The one progress interface: ``progress(done, total, message)``.

Every long computation in nnphd (λ-sweeps, studies, detection, the demos) takes an optional ``progress`` callable
with this signature; ``done`` of ``total`` steps are finished and ``message`` says what is running. The CLI turns it
into a rich progress bar; a notebook may print it or ignore it.
"""

from __future__ import annotations

from typing import Protocol


class Progress(Protocol):
    def __call__(self, done: int, total: int, message: str) -> None: ...


def nested(progress: Progress | None, prefix: str, base: int = 0, total: int | None = None) -> Progress | None:
    """A progress callable for a part of a larger job: messages get ``prefix``; with ``total`` the part's steps
    count from ``base`` in the job's ``total``."""
    if progress is None:
        return None

    def inner(done: int, tot: int, message: str) -> None:
        progress(base + done if total is not None else done, total if total is not None else tot, f"{prefix}{message}")

    return inner


class Stages:
    """A job of ``total`` named stages reported through a :class:`Progress`: each call ``stages("what now")``
    reports the stages done so far and the one that starts."""

    def __init__(self, progress: Progress | None, total: int, prefix: str = ""):
        self.progress, self.total, self.prefix, self.done = progress, int(total), prefix, 0

    def __call__(self, message: str) -> None:
        if self.progress is not None:
            self.progress(min(self.done, self.total), self.total, f"{self.prefix}{message}")
        self.done += 1
