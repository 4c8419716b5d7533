"""The settings of a detection, checked before any work: the law-ranking level, the conservative field (learned, or
declared uniform), the families and your own laws, and whether a declared field suits the record. Each bad setting
is a ValueError (or a :class:`nnphd.io.errors.DataError` for the record) with one line naming it and what is
expected — the command line and :class:`nnphd.NNPhD` check the same way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields
from dataclasses import field as dc_field

import numpy as np

from nnphd.explain.search import DECLARED_FIELDS
from nnphd.io.errors import DataError

__all__ = ["FIELDS", "DetectSettings", "check_declared_field", "check_field", "check_law_fit", "check_settings"]


@dataclass(frozen=True)
class DetectSettings:
    """The settings of one detection (:func:`nnphd.user.detect.detect_data`), as ``nnphd detect``'s options and
    :class:`nnphd.NNPhD`'s arguments give them: the ``seed``, training ``steps`` per λ, seconds of genetic symbolic
    regression per component ``sr_time``, ``n_seeds``, the derivative ``trim`` and ``derivative_method`` (a name,
    a DerivativeEstimator or a :class:`nnphd.user.derivatives.Derivatives`), ``thin``, your own ``laws``, the law
    ranking ``law_fit``, the conservative ``field``, the law ``families`` (keys and Family objects; None: all),
    where the seeds train (``workers``, ``scheduler``: :func:`nnphd.parallel.run_units`), and ``assess``: the other
    fields of :class:`nnphd.user.assess.AssessSettings` (``width``, ``lambdas``, …)."""

    seed: int = 0
    steps: int = 1000
    sr_time: float = 10.0
    n_seeds: int = 2
    trim: bool | str = "auto"
    laws: Sequence[str] = ()
    law_fit: str = "auto"
    field: str = "learned"
    workers: int | None = 1
    scheduler: str | None = None
    derivative_method: object = "auto"
    families: Sequence | None = None
    thin: bool = True
    assess: dict = dc_field(default_factory=dict)

    @classmethod
    def of(cls, **settings) -> DetectSettings:
        """From keywords: this class's fields, and any other keyword a field of :class:`nnphd.user.assess.AssessSettings`."""
        own = {f.name for f in fields(cls)} - {"assess"}
        return cls(**{k: v for k, v in settings.items() if k in own},
                   assess={k: v for k, v in settings.items() if k not in own})  # fmt: skip

    def report_entry(self, trim: bool, families) -> dict:
        """The report's ``settings``: the run's own (``trim``: the one used; ``families``: those ranked, None when
        all), the derivative method, the families and the thinning only where they are not the defaults."""
        from nnphd.user.derivatives import derivative_name
        from nnphd.user.strategies import family_names

        name = derivative_name(self.derivative_method)
        return {
            "seed": self.seed,
            "steps": self.steps,
            "n_seeds": self.n_seeds,
            "law_fit": self.law_fit,
            "sr_time_per_component_s": self.sr_time,
            "trim": trim,
            "field": self.field,
            **({"derivative_method": name} if name != "auto" else {}),
            **({"families": family_names(families)} if families is not None else {}),
            **({"thin": False} if not self.thin else {}),
            **self.assess,
        }


def check_law_fit(law_fit: str) -> None:
    if law_fit not in ("auto", "pointwise", "trajectory"):
        raise ValueError(f"law_fit must be 'auto', 'pointwise' or 'trajectory', got {law_fit!r}")


# the conservative force the user declares: learned by the LNN (any conservative force, the default), or a uniform
# field — gravity near the ground, or none — for motion that does not oscillate (a throw, a fall, a coast-down).
# Along one arc every force of the state is a force of position, so a learned potential absorbs a drag and such a
# record cannot tell a drag from a field that varies over it (measured on the 2-D throw look-alike, 3 mm noise: a
# uniform field leaves χ²/N = 3.1, the uniform field + drag 0.94, a field varying linearly over the record 1.01 —
# benchmarks/results/friction_laws.json); a physicist filming a throw knows the field is uniform, and says so.
FIELDS = {
    "learned": "learned by the Lagrangian network (any conservative force)",
    "uniform": "declared uniform (gravity near the ground, or none): a constant acceleration, fitted",
    "vertical": "declared uniform and along the last coordinate (gravity, with that coordinate pointing up, e.g. a "
    "level camera's y): its size fitted, no field along the others",
}


def check_field(field: str, law_fit: str = "auto") -> None:
    if field not in FIELDS:
        raise ValueError(f"field must be one of {', '.join(map(repr, FIELDS))}, got {field!r}")
    if field in DECLARED_FIELDS and law_fit == "pointwise":
        raise ValueError(
            "a declared uniform field is judged by a fit of the positions: law_fit must be 'auto' or 'trajectory', "
            "got 'pointwise'"
        )


def check_declared_field(field: str, data, traj, ud, info) -> None:
    """A declared uniform field cannot make motion oscillate (no force of position): refuse an oscillating record
    before any training, with the period found as :func:`nnphd.user.assess.assess` finds it."""
    if field not in DECLARED_FIELDS:
        return
    from nnphd.user.assess import motion_period
    from nnphd.user.sampling import arc_noise

    arc = arc_noise(data, traj, list(ud.coords), info)  # a tracker's correlated noise must not read as swings
    noise = [max(arc["difference"][c], arc["smooth_curve"][c]) if np.isfinite(arc["smooth_curve"][c])
             else arc["difference"][c] for c in ud.coords]  # fmt: skip
    period = motion_period(data, traj, [bool(a) for a in ud.is_angle], noise)
    path = ud.path
    if np.isfinite(period):
        raise DataError(
            f"{path}: the field was declared uniform, under which nothing oscillates, but this record swings back and "
            f"forth (period {period:.4g} in its time unit): it oscillates, or its positions are mostly noise; leave the "
            "field to be learned (field 'learned', the default)"
        )


def check_settings(ud, laws: Sequence[str], law_fit: str, field: str, families=None, method="auto") -> None:
    """Refuse bad settings before any work: the law level, the field, the law families (keys and Family objects)
    and the derivative method (a name, a DerivativeEstimator or a Derivatives), and every ``laws`` entry (a --law)
    parsed on the file's coordinates."""
    from nnphd.explain.families import parse_law
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.strategies import check_families

    check_law_fit(law_fit)
    check_field(field, law_fit)
    check_families(families or ())
    if not isinstance(method, Derivatives):
        Derivatives(method)
    for x in laws:  # fail on a bad --law before any work
        parse_law(x, ud.coords)
