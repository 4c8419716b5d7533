"""The candidate laws (nnphd.explain.families): user laws from SymPy strings, the built-in families' symmetry."""

from __future__ import annotations

import numpy as np
import pytest

from nnphd.explain.families import families, parse_law


@pytest.mark.parametrize(
    "text, msg",
    [
        ("", "empty"),
        ("-c*z_dot", "not the velocity"),
        ("-x_dot", "no free parameter"),
        ("x_dot*(", "cannot read"),
        ("-g*x_dot", "name the component"),
        ("w: -g*w_dot", "not a coordinate"),
        ("-x_dot**c", "linear in at least"),
    ],
)
def test_bad_user_law_is_one_line_error(text, msg):
    coords = ["x", "y"] if msg in ("name the component", "not a coordinate") else ["x"]
    with pytest.raises(ValueError, match=msg) as e:
        parse_law(text, coords)
    assert "\n" not in str(e.value)


def test_families_are_odd_in_velocity_or_explicitly_timed():
    """Every built-in law except the drive changes sign with q̇ (dissipative forms); the drive ignores q̇."""
    rng = np.random.default_rng(2)
    q, v, t = rng.normal(size=(50, 2)), rng.normal(size=(50, 2)), rng.uniform(0, 5, 50)
    for f in families(2, ["x", "y"], np.ones(2)):
        th = np.array([1.3] * len(f.nl_names))
        b, b_rev = f.basis(np, th, q, v, t), f.basis(np, th, q, -v, t)
        if f.key == "drive":
            np.testing.assert_allclose(b, b_rev)
        else:
            np.testing.assert_allclose(b, -b_rev, atol=1e-12)


def test_family_from_spec_rebuilds_every_kind():
    """A saved law's spec (built-in, sparse, perturber, user) gives back the same basis."""
    from nnphd.explain.families import family_from_spec, odd_monomials, perturber_family, sparse_family

    rng = np.random.default_rng(3)
    q, v, t = rng.normal(size=(20, 2)), rng.normal(size=(20, 2)), rng.uniform(0, 5, 20)
    support = np.zeros((2, len(odd_monomials(2))), bool)
    support[0, 0] = support[1, 3] = True
    fams = [
        *families(2, ["x", "y"], np.array([0.5, 2.0])),
        sparse_family(2, ["x", "y"], support),
        perturber_family(["x", "y"]),
        parse_law("x: -c*x_dot*abs(x_dot)**p; y: -c*y_dot", ["x", "y"]),
    ]
    for f in fams:
        g = family_from_spec(f.spec, ["x", "y"])
        assert g.key == f.key and g.coef_names == f.coef_names and g.nl_names == f.nl_names
        th = np.array([1.3] * len(f.nl_names))
        np.testing.assert_array_equal(g.basis(np, th, q, v, t), f.basis(np, th, q, v, t))
    with pytest.raises(ValueError, match="unknown law family spec"):
        family_from_spec({"kind": "nope"}, ["x", "y"])


def test_the_dry_term_is_a_tanh_sign_and_old_model_files_keep_their_algebraic_one():
    """sign(q̇) is smoothed as tanh(q̇/ε), ε = 2 % of the rms speed: slope 1/ε at zero, within 1e-4 of ±1 beyond 5ε
    (the algebraic q̇/√(q̇² + ε²) it replaced is still 2 % short there); a spec without "sign" (a model file saved
    before) rebuilds the algebraic form, and the isotropic 2-D term is the tanh of the speed along v̂."""
    from nnphd.explain.families import COULOMB_EPS, family_from_spec

    eps = COULOMB_EPS * 2.0
    v = np.array([[-5 * eps], [-1e-3 * eps], [0.0], [eps], [5 * eps], [50 * eps]])
    coul = next(f for f in families(1, ["x"], np.array([2.0])) if f.key == "coulomb")
    assert coul.spec["sign"] == "tanh"
    b = -coul.basis(np, np.zeros(0), v, v, np.zeros(len(v)))[:, 0, 0]
    np.testing.assert_allclose(b, np.tanh(v[:, 0] / eps), rtol=1e-12, atol=0)
    assert b[4] > 1 - 1e-4 and b[0] < -1 + 1e-4 and b[2] == 0.0
    old = family_from_spec({k: x for k, x in coul.spec.items() if k != "sign"}, ["x"])
    b_old = -old.basis(np, np.zeros(0), v, v, np.zeros(len(v)))[:, 0, 0]
    np.testing.assert_allclose(b_old, v[:, 0] / np.sqrt(v[:, 0] ** 2 + eps**2), rtol=1e-12)
    assert b_old[4] == pytest.approx(5 / np.sqrt(26))  # 1.9 % short of 1 at 5ε
    mixed = next(f for f in families(1, ["x"], np.array([2.0])) if f.key == "linear+coulomb")
    np.testing.assert_allclose(-mixed.basis(np, np.zeros(0), v, v, np.zeros(len(v)))[:, 0, 1], b, rtol=1e-12)
    # two coordinates: −μ tanh(|v|/ε_all) v̂, and 0 at rest (no division by zero)
    iso = next(f for f in families(2, ["x", "y"], np.array([2.0, 0.0])) if f.key == "coulomb")
    w = np.array([[3 * eps, 4 * eps], [0.0, 0.0], [1e-6 * eps, 0.0]])
    g = -iso.basis(np, np.zeros(0), w, w, np.zeros(3))[:, :, 0]
    np.testing.assert_allclose(g[0], np.tanh(5.0) * np.array([0.6, 0.8]), rtol=1e-12)
    np.testing.assert_array_equal(g[1], [0.0, 0.0])
    assert g[2, 0] == pytest.approx(1e-6, rel=1e-6) and g[2, 1] == 0.0
    with pytest.raises(ValueError, match="unknown smoothed sign"):
        families(1, ["x"], np.ones(1), sign="erf")
