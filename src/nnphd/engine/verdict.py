r"""The verdict: is there new physics? Read off the L_e(λ) curve of a λ-sweep (paper section II.E, Theorem 1).

Theorem 1: for 0 < λ < 1 the minimiser recovers f exactly (L_e → 0) and the UAN carries f_n; for λ > 1 the UAN is
switched off and L_e → ‖f − f_c‖ = ‖f_n‖. Conservative dynamics therefore shows no jump of L_e at λ = 1, and
non-conservative dynamics shows a jump whose height is the size of f_n.

The statistic:

* ``L_below`` — median of L_e over 0.05 ≤ λ < 1 (the paper's robust range; all λ < 1 if none fall there),
* ``L_above`` — median of L_e over λ > 1,
* ``ratio``  = L_above / L_below (how many times the error grows across λ = 1),
* ``relative_size`` = L_above / ‖f‖_p — the non-conservative force as a fraction of the whole force, in the loss norm.

New physics is declared when ``ratio ≥ min_ratio`` *and* ``relative_size ≥ min_relative_size``: the error must jump,
and the jump must be more than numerical noise (1e-4 of the force: "new physics" is often a small perturbation —
friction is 0.7% and gravitational radiation 0.15% of the force on the paper's Table I trajectories). The estimated non-conservative force is reported two ways:
L_above (the error the conservative model cannot remove) and L_b just below λ = 1 (the size of the UAN's output).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from nnphd.engine.train import SweepPoint, pnorm

MIN_RATIO = 3.0
MIN_RELATIVE_SIZE = 1e-4


@dataclass(frozen=True)
class PhaseTransition:
    """The paper's verdict from a λ-sweep: does the held-out error L_e jump across λ = 1 (``ratio`` of the medians
    above and below, at least ``min_ratio``), by a remainder large enough to matter (``relative_size``)? The user's
    verdict on a recording is :class:`nnphd.api.Verdict`."""

    new_physics: bool
    ratio: float
    jump: float
    L_below: float
    L_above: float
    relative_size: float
    force_norm: float
    fn_size_from_jump: float
    fn_size_from_uan: float
    min_ratio: float
    min_relative_size: float
    reason: str

    def to_dict(self) -> dict:
        return asdict(self)


def _median(points: Sequence[SweepPoint], lo: float, hi: float, attr: str = "L_e") -> float | None:
    vals = [getattr(p, attr) for p in points if lo <= p.lam < hi]
    return float(np.median(vals)) if vals else None


def _first_not_none(*vals):
    return next((v for v in vals if v is not None), None)


def verdict(
    points: Sequence[SweepPoint],
    force_norm: float,
    min_ratio: float = MIN_RATIO,
    min_relative_size: float = MIN_RELATIVE_SIZE,
) -> PhaseTransition:
    """Verdict from a λ-sweep. ``force_norm`` is ‖f‖ of the evaluation labels in the same norm as L_e."""
    below = _first_not_none(_median(points, 0.05, 1.0), _median(points, 0.0, 1.0))
    above = _median(points, 1.0 + 1e-12, np.inf)
    if below is None or above is None:
        raise ValueError("the λ grid must contain values below and above 1 to read the phase transition")
    uan = _first_not_none(_median(points, 0.05, 1.0, "L_b"), _median(points, 0.0, 1.0, "L_b"))
    tiny = 1e-12 * max(force_norm, 1e-300)
    ratio = above / max(below, tiny)
    rel = above / force_norm if force_norm > 0 else 0.0
    is_new = bool(ratio >= min_ratio and rel >= min_relative_size)
    if is_new:
        reason = (
            f"L_e jumps {ratio:.1f}x across λ=1 ({below:.3g} → {above:.3g}); the part no Lagrangian explains is "
            f"{100 * rel:.1f}% of the force"
        )
    elif ratio < min_ratio:
        reason = f"no jump of L_e across λ=1 (x{ratio:.2f} < x{min_ratio:g}): a Lagrangian explains the force"
    else:
        reason = (
            f"L_e grows x{ratio:.1f} across λ=1 but the remainder is only {100 * rel:.2f}% of the force "
            f"(< {100 * min_relative_size:g}%): within the conservative model's accuracy"
        )
    return PhaseTransition(
        new_physics=is_new,
        ratio=float(ratio),
        jump=float(above - below),
        L_below=below,
        L_above=above,
        relative_size=float(rel),
        force_norm=float(force_norm),
        fn_size_from_jump=above,
        fn_size_from_uan=float(uan),
        min_ratio=min_ratio,
        min_relative_size=min_relative_size,
        reason=reason,
    )


def force_norm(qdd, p) -> float:
    """‖f‖ of the labels in the loss norm (for 'mse': the mean square)."""
    import jax.numpy as jnp

    return float(pnorm(jnp.asarray(qdd), p))
