"""A nonlinear family at a value of its parameter that makes it a simpler family (nnphd.explain.table.SPECIAL_VALUES:
the power law −k(|q̇|²)^m q̇ is viscous at m = 0 and quadratic drag at m = ½) within Z_TERM standard errors is not
eligible when that simpler family is ranked beside it — as a term within Z_TERM standard errors of zero: the simpler
family is the law (the law table's 2-D quadratic drag was once claimed as a power law m = 0.476 ± 0.017)."""

from __future__ import annotations

import numpy as np
import pytest

from nnphd.explain.families import families
from nnphd.explain.table import Z_TERM, law_row, select_law, zero_row


def _table(m, se_m, keys=("power", "quadratic", "linear"), n=2, ic=None):
    names = ["x", "y"][:n]
    fams = {f.key: f for f in families(n, names, np.ones(n))}
    rows = [zero_row(names, 1.0, 10, "trajectory")]
    rows[0].ic = 0.0
    ic = ic or {"power": -1000.0, "quadratic": -990.0, "linear": -400.0}  # the power law 10 ahead of quadratic drag
    for key in keys:
        fam = fams[key]
        theta = [m] if key == "power" else []
        se = [0.0005] + ([se_m] if key == "power" else [])
        r = law_row(fam, np.array([0.05]), np.array(theta, float), np.array(se), names, 0.1, "trajectory")
        r.ic, r.delta_ic, r.fn_rel = ic[key], ic[key], 0.1
        rows.append(r)
    return select_law(rows, 1000.0, 1.0, "folds", {})


@pytest.mark.parametrize("n", [1, 2])
def test_a_power_law_at_quadratic_drags_exponent_gives_way_to_it(n):
    tab = _table(0.476, 0.017, n=n)  # 1.4 standard errors from ½
    assert tab.law.key == "quadratic" and tab.status == "claimed"
    power = next(r for r in tab.rows if r.key == "power")
    assert not power.significant and "power law's exponent" in tab.reason


def test_a_power_law_at_viscous_exponent_gives_way_to_it():
    tab = _table(0.01, 0.02, ic={"power": -1000.0, "quadratic": -400.0, "linear": -990.0})
    assert tab.law.key == "linear"


@pytest.mark.parametrize("m", [0.5 - 1.01 * Z_TERM * 0.017, 0.5 + 1.01 * Z_TERM * 0.017, 0.3, 1.2])
def test_a_power_law_clear_of_the_special_values_stays(m):
    tab = _table(m, 0.017)
    assert tab.law.key == "power" and tab.law.params["m"] == pytest.approx(m)


def test_without_the_simpler_family_beside_it_the_power_law_stays():
    tab = _table(0.49, 0.017, keys=("power", "linear"))  # (e.g. --families power,linear)
    assert tab.law.key == "power"
