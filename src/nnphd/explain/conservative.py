r"""The conservative part of the joint model: f_c is linear in its coefficients α — a per-coordinate scale of a
given conservative force (the LNN's f_c, or a feature Lagrangian's), plus a correction library that is even under
time reversal (q̇ → −q̇), as every force from a Lagrangian T(q, q̇) − V(q) is — gradients of potential monomials in
the positions up to degree 4 (angles enter as sin θ, cos θ; gradients, not free per-coordinate polynomials, because
on an orbit the velocity is a rotation of the position and a curl field would absorb friction), the quadratic
velocity terms q̇_j q̇_k (Christoffel-type) — and the one time-reversal-odd conservative force, the gyroscopic
(magnetic-type) term B q̇ with B antisymmetric (:func:`conservative_basis`).
"""

from __future__ import annotations

import numpy as np

from nnphd.explain.families import eye_columns

__all__ = ["conservative_basis"]


def _position_features(xp, q, angles, center=None):
    """sin θ, cos θ of angles; other coordinates centred and scaled by ``center`` = (mean, std) (n,) each.
    Returns (u (N, d), du (N, d), owner (d,)): the features, their derivatives along their coordinate, and which
    coordinate each belongs to."""
    feats, ders, owner = [], [], []
    for j in range(q.shape[1]):
        if angles[j]:
            s_, c_ = xp.sin(q[:, j]), xp.cos(q[:, j])
            feats += [s_, c_]
            ders += [c_, -s_]
            owner += [j, j]
        else:
            m, sd = (center[0][j], center[1][j]) if center is not None else (0.0, 1.0)
            feats.append((q[:, j] - m) / sd)
            ders.append(xp.ones_like(q[:, j]) / sd)
            owner.append(j)
    return xp.stack(feats, axis=1), xp.stack(ders, axis=1), owner


def _pot_monomials(d: int, deg: int | None = None) -> list[tuple[int, ...]]:
    """Exponents of the potential monomials in d position features: degree 1…4 (1…3 beyond two features), or
    1…``deg``."""
    import itertools

    deg = deg or (4 if d <= 2 else 3)
    return sorted(
        (e for e in itertools.product(range(deg + 1), repeat=d) if 0 < sum(e) <= deg), key=lambda e: (sum(e), e[::-1])
    )


def _potential_gradients(xp, q, angles, center, library):
    """(N, n, M) columns −∂V_e/∂q … of the potential monomials V_e in the position features that ``library`` keeps
    (see :func:`conservative_basis`): each column the gradient of one monomial, mapped back to the coordinates."""
    n = q.shape[1]
    u, du, owner = _position_features(xp, q, angles, center)
    d = u.shape[1]
    onehot = np.zeros((d, n))
    onehot[np.arange(d), owner] = 1.0
    onehot = xp.asarray(onehot, dtype=q.dtype)
    grads = []
    mons = _pot_monomials(d, 1 if library in ("minimal", "vertical") else (3 if library == "short" else None))
    if library == "vertical":  # the uniform field along the last feature alone (gravity with that coordinate up)
        mons = [e for e in mons if e[-1] == 1]
    if library == "short":  # the angles' sin/cos to degree 1 (a pendulum about any rest angle), the rest to 3
        is_ang = [bool(angles[o]) for o in owner]
        mons = [e for e in mons if sum(k for k, a in zip(e, is_ang) if a) <= 1 and (sum(e) == 1 or not any(
            k and a for k, a in zip(e, is_ang)))]  # fmt: skip
    for e in mons:
        parts = []
        for f in range(d):  # ∂V_e/∂u_f
            if e[f] == 0:
                parts.append(xp.zeros_like(q[:, 0]))
                continue
            c = e[f] * u[:, f] ** (e[f] - 1)
            for g, k in enumerate(e):
                if g != f and k:
                    c = c * u[:, g] ** k
            parts.append(c)
        dV = xp.stack(parts, axis=1) * du  # (N, d): ∂V/∂u_f · du_f/dq_owner(f)
        grads.append(dV @ onehot)  # (N, n)
    return xp.stack(grads, axis=2)


def _velocity_columns(xp, q, v) -> list:
    """The velocity-dependent conservative columns: the quadratic terms q̇_a q̇_b (N, n, n·M) per coordinate, and
    (n ≥ 2) the antisymmetric gyroscopic term (N, n, n(n−1)/2)."""
    N, n = q.shape
    cols = []
    pc = []
    for a in range(n):
        for b in range(a, n):
            pc.append(v[:, a] * v[:, b])
    P = xp.stack(pc, axis=1)  # (N, M)
    cols.append((P[:, None, :, None] * xp.eye(n, dtype=q.dtype)[None, :, None, :]).reshape(N, n, -1))
    if n >= 2:
        g = []
        for a in range(n):
            for b in range(a + 1, n):
                col = xp.zeros_like(q)
                col = col + v[:, b][:, None] * (xp.arange(n) == a)[None] - v[:, a][:, None] * (xp.arange(n) == b)[None]
                g.append(col)
        cols.append(xp.stack(g, axis=2))
    return cols


def conservative_basis(xp, q, v, angles, fc=None, center=None, library: bool = True):
    """(N, n, Kc) columns of the conservative model (see the module docstring): per-coordinate scale of ``fc``
    (if given); gradients −∂V_e/∂q of potential monomials V_e in the position features (degree ≤ 4, ≤ 3 beyond two
    features; angles enter as sin θ, cos θ) — curl-free, so that no combination of them is a rotation field, which
    on an orbit would mimic friction (v ∝ a rotation of q); quadratic velocity terms; and the antisymmetric
    gyroscopic term (n ≥ 2). ``library=False``: the scale of ``fc`` alone (when ``fc`` comes from a trusted form,
    e.g. a system's feature Lagrangian); ``library="minimal"``: ``fc``'s scale and the uniform field (degree-1
    potentials) only (``"vertical"``: along the last coordinate alone) — for motion that does not oscillate (a throw, a fall), where one arc visits each position once
    and any force of time is a force of position along it: a richer library absorbs the drag; ``"short"``: ``fc``'s
    scale, sin θ and cos θ of angles to degree 1 (−a sin(θ − θ₀)), other coordinates' potentials to degree 3, no
    velocity terms — for a record of a few periods, where the full library's ~15 shapes trade against the friction
    (a servo drop's dry friction went into them)."""
    N, n = q.shape
    cols = []
    if fc is not None:
        cols.append(eye_columns(xp, fc))
    if not library:
        if fc is None:
            raise ValueError("library=False needs a conservative force fc")
        return cols[0]
    cols.append(_potential_gradients(xp, q, angles, center, library))
    if library in ("minimal", "short", "vertical"):
        return xp.concatenate(cols, axis=2)
    cols += _velocity_columns(xp, q, v)
    return xp.concatenate(cols, axis=2)
