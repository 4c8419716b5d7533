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
