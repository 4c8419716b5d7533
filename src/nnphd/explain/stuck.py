r"""A stuck phase as evidence about the law of friction.

A body at rest off its equilibrium — q̇ = q̈ = 0 where the conservative force f_c(q) is not zero — is held there by a
force that does not vanish at zero speed: dry (Coulomb) friction's static part. Viscous friction, quadratic drag, a
Rayleigh or van der Pol term all vanish at q̇ = 0, so under any of them the body would start again towards its
equilibrium and oscillate about it: a law without a dry term cannot be the law of such a record, whatever its fit of
the swings. Measured: a dry-friction look-alike that rests its last 2.3 s 0.015 rad off the equilibrium bars viscous +
quadratic, Rayleigh and van der Pol candidates (z 6–9); a real servo drop resting 0.007 rad from the equilibrium its
swings imply bars nothing — with one drop of three periods that equilibrium is known to ±0.009 rad (z 0.8).

Rule (:func:`stuck_contradictions`): each candidate's joint trajectory-level fit gives its conservative force
f_c(q; α̂) with a covariance of α̂ (widened by the residuals' correlation time τ). A candidate whose law has no term
that stays finite as q̇ → 0 (no sign(q̇)) is contradicted by a stuck stretch at q_s when

- its conservative force there is significant: |f_c(q_s)| ≥ :data:`Z_STUCK`·se, and
- the offset from its equilibrium, |f_c(q_s)| / |∂f_c/∂q|, is at least :data:`OFFSET_MIN` rest tolerances (the
  tolerance by which the rest detector calls a stretch still: 1.5 σ + ½ quantization step) — so that the motion the
  candidate predicts from there would have been seen.

Only a rest that ends its trajectory counts (a body held before its release, or one that moves again, was held or
pushed from outside), only near a stable equilibrium of the fit (∂f_c/∂q < 0: a uniform field or a hilltop says
nothing), and only for oscillating records (``nnphd.user.detect.find_law``). A contradicted candidate is not
eligible; the stuck stretch and the force each candidate leaves unbalanced are in its row (``stuck``). Candidates with a dry term are not judged by their μ against the force at rest: static friction
may exceed the sliding friction the fit measures. One coordinate only (the rest positions are points on a line).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

__all__ = ["OFFSET_MIN", "Z_STUCK", "bar_stuck", "holds_at_rest", "stuck_contradictions"]

Z_STUCK = 3.0
OFFSET_MIN = 3.0


def holds_at_rest(row) -> bool:
    """Whether a law has a term that stays finite as q̇ → 0: a dry term (sign(q̇) among its family's terms or in its
    formula — a user's law)."""
    terms = row.family.terms if row.family is not None else ()
    return any("sign(" in x for x in terms) or any("sign(" in f for f in row.formula.values())


def stuck_contradictions(table, stretches, *, angles, fc_fn=None) -> dict:
    """{family key: {"q", "force", "se", "offset", "tolerance", "seconds"}} for the candidates of a trajectory-level
    ``table`` (one coordinate) that a stuck stretch contradicts (see the module docstring). ``stretches``: dicts with
    "q" (the mean position, (n,)), "seconds" (its duration) and "tolerance" (the rest tolerance, (n,));
    ``fc_fn(q, v)`` (JAX) the conservative force the table was fitted beside, if any."""
    from nnphd.explain.conservative import conservative_basis

    settings = table.settings
    if settings.get("method") != "trajectory" or not stretches or len(settings.get("names", [])) != 1:
        return {}
    center, library = settings.get("_center"), settings.get("library", True)

    def columns(q):  # (n, Kc) conservative columns at the positions q (1, n), at rest
        q = np.asarray(q, float).reshape(1, -1)
        v = np.zeros_like(q)
        fc = None if fc_fn is None else np.asarray(fc_fn(q, v), float).reshape(1, -1)
        return np.asarray(conservative_basis(np, q, v, angles, fc, center, library), float)[0]

    at = []  # per stretch: the columns at the rest and their slope (the same for every row)
    for s in stretches:
        qs = np.asarray(s["q"], float).reshape(-1)
        tol = float(np.asarray(s["tolerance"], float).reshape(-1)[0])
        h = max(1e-4 * max(abs(qs[0]), 1.0), tol)
        at.append((s, qs, tol, columns(qs)[0], (columns(qs + h)[0] - columns(qs - h)[0]) / (2 * h)))
    out = {}
    for r in table.rows:
        a, cov = r.conservative, r.conservative_cov
        if r.family is None or a is None or cov is None or holds_at_rest(r):
            continue
        for s, qs, tol, B, dB in at:
            if len(B) != len(a):
                continue
            force, slope = float(B @ a), float(dB @ a)
            se = float(np.sqrt(max(B @ cov @ B, 0.0)))
            if not slope < 0:  # no stable equilibrium nearby (a uniform field, a hilltop): nothing to say
                continue
            offset = abs(force / slope)
            if abs(force) >= Z_STUCK * se and offset >= OFFSET_MIN * tol:
                out[r.key] = {
                    "q": float(qs[0]),
                    "force": force,
                    "se": se,
                    "offset": float(offset),
                    "tolerance": tol,
                    "seconds": float(s["seconds"]),
                }
                break
    return out


def bar_stuck(table, contradicted: dict):
    """``table`` with the ``contradicted`` families (:func:`stuck_contradictions`) not eligible, ranked again (a
    candidate the amplitude envelope preferred that is contradicted bars nothing); unchanged when none is."""
    from nnphd.explain.envelope import _blocked_by_disagreement
    from nnphd.explain.table import _select

    if not contradicted or not any(r.key in contradicted for r in table.rows):
        return table
    rows = []
    for r in table.rows:
        if r.key in contradicted and r.family is not None:
            env = None if r.envelope is None else {**r.envelope, "eligible_but_agreement": False}
            r = replace(r, significant=False, stuck=contradicted[r.key], envelope=env)
        rows.append(r)
    out = _select(rows, table.n_eff, table.tau, table.folds, table.settings, judge=False)
    blocked = _blocked_by_disagreement(out)
    if blocked is not None:  # as in nnphd.explain.envelope: a candidate the envelope clearly prefers bars the law
        out.law, out.ties, out.blocked = None, [], blocked
        zero = [r for r in out.rows if r.key == "none"]
        out.rows = [*zero, blocked, *(r for r in out.rows if r is not blocked and r.key != "none")]
        out.reason = (
            f"no law is claimed: the amplitude envelope clearly prefers {blocked.title}, whose windows do not reject "
            "it, but its two fits disagree on its coefficients"
        )
    c = next(iter(contradicted.values()))
    out.reason += (
        f"; not eligible, as the record rests {c['seconds']:.2g} s at q = {c['q']:.4g}, {c['offset']:.2g} from the "
        f"equilibrium of their fits (their conservative force there {c['force']:.3g} ± {c['se']:.2g}) and nothing in "
        f"them acts at zero speed: {', '.join(sorted(contradicted))}"
    )
    return out
