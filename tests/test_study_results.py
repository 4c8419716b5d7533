"""The typed results of the paper's studies (LambdaPResult, DataQualityResult, PredictionResult): to_dict is
results.json's content (keys, order, values), from_dict rebuilds it and refuses a wrong field by name. Built from
hand-made dicts (numbers of short runs, rounded): no training."""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys
import time
from dataclasses import FrozenInstanceError, fields
from pathlib import Path

import pytest

import nnphd
from nnphd.io.results import json_default, write_results
from nnphd.paper.study_results import (
    AlphaRow,
    BetaRow,
    Claim,
    CurveRow,
    DataQualityResult,
    LambdaPResult,
    ModelMetrics,
    PredictionResult,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.fixtures.edit import set_item  # noqa: E402


def _dump(x) -> str:  # as write_json writes results.json
    return json.dumps(x, indent=2, default=json_default, allow_nan=True)


def _curve_row(lam, L_e, m_c):
    return {
        "lam": lam, "L_e": L_e, "L_b": 0.5 / lam, "L_e_train": L_e * 1.1, "L_b_train": 0.4 / lam, "m_c": m_c,
        "m_n": m_c / 2, "fn_rms": 0.2 / lam, "m_c_median": m_c * 0.8, "m_n_median": m_c * 0.4,
    }  # fmt: skip


def _lambda_p() -> dict:
    """A λ/p study's results dict: HO+LD under p = 1 and MSE, two λ; forces recorded for p = 1 only."""
    curves = {"ho+ld": {"1": [_curve_row(0.1, 0.0123, 0.031), _curve_row(2.0, 0.4871, 0.027)],
                        "mse": [_curve_row(0.1, 0.0021, 0.052), _curve_row(2.0, 0.1213, 0.044)]}}  # fmt: skip

    def verdict(p, ratio, kind, sharp, cached):
        return {
            "system": "ho+ld", "p": p, "truth_conservative": False, "new_physics": True, "correct": True,
            "ratio": ratio, "L_below": 0.0123, "L_above": 0.4871, "relative_size": 0.6931, "reason": "L_e jumps",
            "sharpness": sharp, "transition": kind, "rise_fraction": 0.97, "train_wall_time_s": 3.25, "cached": cached,
        }  # fmt: skip

    return {
        "settings": {
            "systems": ["ho+ld"],
            "ps": ["1", "mse"],
            "lambdas": [0.1, 2.0],
            "steps_per_lambda": 30,
            "seed": 0,
        },
        "evaluated_on": "test set (L_e, L_b, m_c, m_n, forces)",
        "curves": curves,
        "verdicts": [verdict("1", 39.6016, "jump", math.inf, False), verdict("mse", 57.7619, "ambiguous", None, True)],
        "alignment": {
            "system": "ho+ld",
            "truth": "f_c = −q, f_n = −½q̇",
            "fn_true_rms": 0.4987,
            "by_p": {  # the curves' columns
                l: [{k: r[k] for k in ("lam", "m_c", "m_n", "fn_rms")} for r in rows]
                for l, rows in curves["ho+ld"].items()
            },
            "forces": {
                "1": {
                    "evaluated_on": "first 3 test points",
                    "q": [0.5, -1.25, 2.0],
                    "qd": [1.0, 0.25, -0.75],
                    "fc_true": [-0.5, 1.25, -2.0],
                    "fn_true": [-0.5, -0.125, 0.375],
                    "by_lambda": {
                        "0.1": {"lam": 0.1, "fc": [-0.49, 1.26, -1.98], "fn": [-0.51, -0.12, 0.37]},
                        "2": {"lam": 2.0, "fc": [-0.98, 1.1, -1.7], "fn": [0.001, -0.002, 0.0]},
                    },
                },
                "mse": None,
            },
        },
        "claims": [
            {
                "claim": "L_e jumps at λ=1 (verdict: new physics) for ho+ld with p=1",
                "ours": "ho+ld p=1: ×39.6",
                "met": True,
            },
            {"claim": "MSE loss gives a smooth (second-order) transition", "ours": "ho+ld: sharpness —", "met": False},
        ],
        "cached": ["ho+ld/p=mse"],
        "train_wall_time_s": 6.5,
        "compile_time_s": 12.75,
        "wall_time_s": 20.5,
        "jax_version": "0.10.2",
    }


def _grid(kind: str, system: str, rows: list[dict], cached: bool) -> dict:
    return {
        "settings": {
            "kind": kind,
            "system": system,
            "lam": 10.0 if kind == "alpha" else 0.5,
            "grid": [r[kind] for r in rows],
        },
        "table": rows,
        "train_wall_time_s": 4.5 if kind == "alpha" else 2.25,
        "evaluated_on": "L_e, L_b, m_c, m_n: held-out test set from the same distribution as the training set",
        "fingerprint": "8dd21ba7cd530b19",
        "cached": cached,
    }


def _dq_row(kind: str, x: float, L_e: float, m_c: float) -> dict:
    return {
        kind: x, "L_e": L_e, "L_b": 0.0012, "L_e_train": L_e * 0.9, "L_e_full": 0.6648, "fn_size": 0.5 * x,
        "m_c": m_c, "m_n": 0.4998, "m_c_train": m_c * 1.1, "m_n_train": 0.49, "m_c_full": 1.4757, "m_n_full": 1.2398,
        "m_c_median": m_c * 0.7, "m_n_median": 0.48, "frac_qd_pos": x,
    }  # fmt: skip


def _data_quality() -> dict:
    alpha = _grid("alpha", "ho+cd", [_dq_row("alpha", 0.25, 0.0031, 0.21), _dq_row("alpha", 1.0, 0.4986, 0.33)], True)
    beta = _grid("beta", "ho+ld", [_dq_row("beta", 0.5, 0.0102, 0.055), _dq_row("beta", 1.0, 0.0211, 0.331)], False)
    return {
        "settings": {"steps": 300, "seed": 1, "alphas": [0.25, 1.0], "betas": [0.5, 1.0], "p": 1.0},
        "evaluated_on": alpha["evaluated_on"],
        "alpha": alpha,
        "beta": beta,
        "claims": [{"claim": "HO+CD, λ=10: L_e nearly zero for α ≤ 0.5", "ours": "max L_e = 0.0031", "met": True}],
        "cached": ["alpha"],
        "train_wall_time_s": 6.75,
        "wall_time_s": 7.5,
        "jax_version": "0.10.2",
    }


def _metrics(e: float, tx: float | None) -> dict:
    return {
        "theta1_rmse_30_40": 0.0123, "theta1_rmse_30_200": 0.4567, "energy_rmse_30_200": e, "t_error_exceeds_0.1": tx,
        "diverged_at": None, "train_force_error": 0.0821, "train_force_rel_error": 0.0734,
    }  # fmt: skip


def _prediction() -> dict:
    return {
        "experiment": "prediction (paper section III.B, Fig. 4): damped double pendulum, train t ≤ 30, extrapolate",
        "settings": {"seed": 1, "steps": 200, "lambda": 0.2, "widths": [32, 32], "t_split": 30.0},
        "metrics": {"nnphd": _metrics(0.0351, 41.3), "lnn": _metrics(0.2306, 31.0), "blackbox": _metrics(6.1484, None)},
        "truth": {"energy_t_split": -2.4767, "energy_t_end": -2.5252, "energy_loss": 0.0485},
        "lnn_energy_constancy": {
            "true_energy_loss": 0.0485,
            "truth_window_mean_drift": -0.0412,
            "lnn_true_energy_window_mean_drift": 0.0011,
            "lnn_true_energy_drift_over_truth_drift": 0.0267,
            "lnn_learned_energy_range": 6.13e-08,
            "lnn_learned_energy_range_on_true_states": 0.8889,
            "lnn_learned_energy_range_ratio": 6.9e-08,
        },  # fmt: skip
        "decomposition": {
            "what": "NNPhD's f_n against the true friction",
            "fn_true_rms_train": 0.0129,
            "fn_learned_rms_train": 0.0131,
            "fn_rel_error_train": 0.051,
            "fn_true_rms_test": 0.0116,
            "fn_learned_rms_test": 0.0119,
            "fn_rel_error_test": 0.062,
        },  # fmt: skip
        "energy_balance": {
            "what": "dH/dt of the learned energy against the learned dissipated power",
            "rollout_finite": True,
            "dHdt_vs_power_rel_rms": 0.00076,
            "dHdt_vs_power_corr": 0.99999944,
            "dHdt_vs_naive_fn_dot_qd_rel_rms": 0.2031,
            "mean_dHdt": -0.0315,
            "mean_power": -0.0316,
            "learned_energy_scale_alpha": 3.7091,
            "learned_vs_true_power_corr": 0.9218,
            "learned_vs_true_power_rel_rms": 0.5845,
            "learned_vs_alpha_true_power_rel_rms": 0.0903,
            "mean_learned_power_over_mean_true_power": 3.6936,
        },  # fmt: skip
        "claims": [
            {"claim": "NNPhD energy RMSE over [30, 200] < the LNN's", "ours": "NNPhD 0.0351 vs LNN 0.2306", "met": True}
        ],
        "jax_version": "0.10.2",
        "train_time_s": {"nnphd": 12.5, "lnn": 8.25, "blackbox": 6.0},
        "wall_time_s": 31.5,
    }


CASES = [(LambdaPResult, _lambda_p), (DataQualityResult, _data_quality), (PredictionResult, _prediction)]


@pytest.mark.parametrize("cls,make", CASES)
def test_round_trip_gives_the_same_dict_and_bytes(cls, make):
    d = make()
    res = cls.from_dict(copy.deepcopy(d))
    out = res.to_dict()
    assert out == d and list(out) == list(d) and _dump(out) == _dump(d)
    again = cls.from_dict(json.loads(_dump(out)))
    assert again == res and again.to_dict() == d


@pytest.mark.parametrize("cls,make", CASES)
def test_result_is_frozen_and_to_dict_is_a_copy(cls, make):
    res = cls.from_dict(make())
    with pytest.raises(FrozenInstanceError):
        res.wall_time_s = 0.0
    with pytest.raises(FrozenInstanceError):
        res.claims[0].met = False
    out = res.to_dict()
    out["settings"]["seed"] = 99
    out["claims"][0]["met"] = not out["claims"][0]["met"]
    assert res.to_dict() == make()


def _assert_fields(record, d: dict) -> None:
    """Each field of a flat row holds the value of its key in the dict (the key: its metadata's "key", or its name)."""
    assert [f.metadata.get("key", f.name) for f in fields(record)] == list(d), (type(record).__name__, list(d))
    for f in fields(record):
        assert getattr(record, f.name) == d[f.metadata.get("key", f.name)], (type(record).__name__, f.name)


def _with_claims_met(d: dict, met: list[bool]) -> dict:
    d = copy.deepcopy(d)
    d["claims"] = [{"claim": f"claim {i}", "ours": "x", "met": m} for i, m in enumerate(met)]
    return d


def test_lambda_p_typed_fields_are_the_dicts_and_the_derived_ones_are_recomputed():
    d = _lambda_p()
    res = LambdaPResult.from_dict(copy.deepcopy(d))
    assert list(res.curves) == list(d["curves"])
    for s, by_p in d["curves"].items():
        assert list(res.curves[s]) == list(by_p)
        for p, rows in by_p.items():
            assert len(res.curves[s][p]) == len(rows)
            for row, r in zip(res.curves[s][p], rows):
                assert isinstance(row, CurveRow)
                _assert_fields(row, r)
    assert len(res.verdicts) == len(d["verdicts"])
    for v, dv in zip(res.verdicts, d["verdicts"]):
        _assert_fields(v, dv)
        assert res.verdict(dv["system"], dv["p"]) is v  # found by system and loss
        if dv["p"] != "mse":
            assert res.verdict(dv["system"], float(dv["p"])) is v  # the loss as a number
    with pytest.raises(KeyError, match="no verdict for ho\\+ld with p=2"):
        res.verdict("ho+ld", 2)
    # read off the verdicts and claims: recomputed here from the dict's verdicts and claims
    assert res.cached == tuple(f"{v['system']}/p={v['p']}" for v in d["verdicts"] if v["cached"])
    assert res.train_wall_time_s == math.fsum(v["train_wall_time_s"] for v in d["verdicts"])
    assert res.all_claims_met is all(c["met"] for c in d["claims"])
    # the alignment: its rows repeat the curves' columns; its forces are the dict's arrays, by λ
    al, dal = res.alignment, d["alignment"]
    assert (al.system, al.truth, al.fn_true_rms) == (dal["system"], dal["truth"], dal["fn_true_rms"])
    for p, rows in al.by_p.items():
        cols = [(c.lam, c.m_c, c.m_n, c.fn_rms) for c in res.curves[al.system][p]]
        assert [(r.lam, r.m_c, r.m_n, r.fn_rms) for r in rows] == cols
    assert list(al.forces) == list(dal["forces"])
    for p, f in al.forces.items():
        df = dal["forces"][p]
        if df is None:
            assert f is None
            continue
        assert f.evaluated_on == df["evaluated_on"]
        assert [list(getattr(f, k)) for k in ("q", "qd", "fc_true", "fn_true")] == [
            df[k] for k in ("q", "qd", "fc_true", "fn_true")
        ]
        assert [(f"{a.lam:g}", a.lam, list(a.fc), list(a.fn)) for a in f.by_lambda] == [
            (key, at["lam"], at["fc"], at["fn"]) for key, at in df["by_lambda"].items()
        ]
    for c, dc in zip(res.claims, d["claims"], strict=True):
        _assert_fields(c, dc)


def test_lambda_p_derived_fields_follow_the_verdicts_and_claims():
    """Other cache flags, training times and claims than the fixture's: the derived fields move with them."""
    d = _with_claims_met(_lambda_p(), [True, True, True])
    for v, cached, wall in zip(d["verdicts"], (True, False), (1.25, 40.5)):
        v.update(cached=cached, train_wall_time_s=wall)
    d["cached"], d["train_wall_time_s"] = ["ho+ld/p=1"], 41.75  # as the study writes them
    res = LambdaPResult.from_dict(d)
    assert res.cached == ("ho+ld/p=1",) and res.train_wall_time_s == 1.25 + 40.5 and res.all_claims_met
    assert LambdaPResult.from_dict(_with_claims_met(d, [True, False, True])).all_claims_met is False
    assert LambdaPResult.from_dict(_with_claims_met(d, [])).all_claims_met is True  # none to fail


def test_lambda_p_without_ho_ld_has_no_alignment():
    d = _lambda_p()
    d["alignment"] = None
    res = LambdaPResult.from_dict(d)
    assert res.alignment is None and res.to_dict() == d


def test_data_quality_typed_fields_are_the_dicts_and_the_derived_ones_are_recomputed():
    d = _data_quality()
    res = DataQualityResult.from_dict(copy.deepcopy(d))
    for kind, grid, row_type in (("alpha", res.alpha, AlphaRow), ("beta", res.beta, BetaRow)):
        dg = d[kind]
        assert grid.kind == kind == dg["settings"]["kind"] and grid.settings == dg["settings"]
        assert (grid.train_wall_time_s, grid.evaluated_on, grid.fingerprint, grid.cached) == (
            dg["train_wall_time_s"], dg["evaluated_on"], dg["fingerprint"], dg["cached"]
        )  # fmt: skip
        assert len(grid.table) == len(dg["table"])
        for row, r in zip(grid.table, dg["table"]):
            assert isinstance(row, row_type) and row.fraction == r[kind]
            assert row.to_dict() == r and list(row.to_dict()) == list(r)  # the grid's value first
            assert all(getattr(row, k) == v for k, v in r.items())
    # read off the two grids and the claims: recomputed here from the dict's grids and claims
    assert res.cached == tuple(k for k in ("alpha", "beta") if d[k]["cached"])
    assert res.train_wall_time_s == d["alpha"]["train_wall_time_s"] + d["beta"]["train_wall_time_s"]
    assert res.evaluated_on == d["alpha"]["evaluated_on"]
    assert res.all_claims_met is all(c["met"] for c in d["claims"])
    # with the other cache flags, and a claim not met, they move with them
    d["alpha"]["cached"], d["beta"]["cached"], d["cached"] = False, True, ["beta"]
    d = _with_claims_met(d, [True, False])
    other = DataQualityResult.from_dict(d)
    assert other.cached == ("beta",) and other.all_claims_met is False


def test_prediction_typed_fields_are_the_dicts():
    d = _prediction()
    res = PredictionResult.from_dict(copy.deepcopy(d))
    assert list(res.metrics) == list(d["metrics"])
    for name, m in res.metrics.items():
        assert isinstance(m, ModelMetrics)
        _assert_fields(m, d["metrics"][name])  # t_error_exceeds under its key "t_error_exceeds_0.1"
    for part in ("truth", "lnn_energy_constancy", "decomposition", "energy_balance"):
        _assert_fields(getattr(res, part), d[part])
    for c, dc in zip(res.claims, d["claims"], strict=True):
        _assert_fields(c, dc)
    assert res.train_time_s == d["train_time_s"] and list(res.train_time_s) == list(d["train_time_s"])
    assert (res.experiment, res.settings, res.jax_version, res.wall_time_s) == (
        d["experiment"], d["settings"], d["jax_version"], d["wall_time_s"]
    )  # fmt: skip
    assert res.all_claims_met is all(c["met"] for c in d["claims"])
    assert PredictionResult.from_dict(_with_claims_met(d, [True, False])).all_claims_met is False


def test_nan_survives_the_round_trip():
    d = _prediction()
    d["energy_balance"].update(rollout_finite=False, dHdt_vs_power_rel_rms=math.nan)
    d["metrics"]["blackbox"].update(diverged_at=33.2, energy_rmse_30_200=math.inf)
    res = PredictionResult.from_dict(json.loads(_dump(d)))
    assert math.isnan(res.energy_balance.dHdt_vs_power_rel_rms) and res.metrics["blackbox"].diverged_at == 33.2
    assert _dump(res.to_dict()) == _dump(d)
    lp = _lambda_p()
    lp["verdicts"][0]["train_wall_time_s"] = math.nan
    lp["train_wall_time_s"] = math.nan  # the sum of a NaN: NaN, and that agrees
    assert math.isnan(LambdaPResult.from_dict(json.loads(_dump(lp))).train_wall_time_s)


def test_row_types_name_the_dict_keys():
    assert [f.name for f in fields(Claim)] == ["claim", "ours", "met"]
    assert list(ModelMetrics.from_dict(_metrics(0.1, None)).to_dict()) == list(_metrics(0.1, None))
    assert list(AlphaRow.from_dict(_dq_row("alpha", 0.5, 0.1, 0.2)).to_dict()) == list(_dq_row("alpha", 0.5, 0.1, 0.2))


def _set(d: dict, path: str, value) -> dict:
    """``d`` with the item at ``path`` ("a/b/0/c") replaced (or removed, for value ...)."""
    return set_item(d, path, value)


@pytest.mark.parametrize(
    "path,value,message",
    [
        ("curves/ho+ld/1/0/L_e", "x", r"curves.ho\+ld.1\[0\].L_e must be a number, got 'x'"),
        ("curves/ho+ld/mse/1/fn_rms", ..., r"curves.ho\+ld.mse\[1\] has no 'fn_rms'"),
        ("curves/ho+ld/1", {}, r"curves.ho\+ld.1 must be a list"),
        ("verdicts/0/correct", False, r"verdicts\[0\].correct is False, but new_physics and truth_conservative"),
        ("verdicts/1/transition", "steep", r"verdicts\[1\].transition must be one of jump, smooth"),
        ("verdicts/1/sharpness", "inf", r"verdicts\[1\].sharpness must be a number or null"),
        ("verdicts/0/p", "2", r"verdicts are for \[\('ho\+ld', '2'\)"),
        ("cached", [], r"cached is \[\], the parts' are \['ho\+ld/p=mse'\]"),
        ("train_wall_time_s", 99.0, "train_wall_time_s is 99.0, the sum of the parts' is 6.5"),
        ("compile_time_s", None, "compile_time_s must be a number, got None"),
        ("settings/ps", ..., "settings has no 'ps'"),
        ("settings/lambdas", [0.1, 5.0], r"curves.ho\+ld.1: its λ are not settings.lambdas"),
        ("settings/systems", ["ho+cd"], r"settings.systems is \['ho\+cd'\], the curves' are \['ho\+ld'\]"),
        ("alignment/by_p/1/0/m_c", 0.9, r"alignment.by_p.1 does not repeat curves.ho\+ld.1"),
        ("alignment/system", "ho+cd", r"alignment.system 'ho\+cd' has no curves"),
        ("alignment/forces/mse", ..., r"alignment.forces has the losses \['1'\], by_p \['1', 'mse'\]"),
        ("alignment/forces/1/fn_true", [0.1], "alignment.forces.1.fn_true has 1 values, q has 3"),
        ("alignment/forces/1/by_lambda/2/lam", 5.0, "alignment.forces.1.by_lambda.2: the key must be its λ, 5"),
        ("alignment/forces/1/by_lambda/0.1/fc/1", None, r"alignment.forces.1.by_lambda.0.1.fc\[1\] must be a number"),
        ("alignment/forces/1/by_lambda/2/fn", [0.0], "alignment.forces.1.by_lambda.2.fn has 1 values, q has 3"),
        ("claims/0/met", "yes", r"claims\[0\].met must be a bool, got 'yes'"),
        ("claims/1/paper", "x", r"claims\[1\] has an unknown key 'paper'"),
        ("jax_version", 10, "jax_version must be a string"),
        ("extra", 1, "the result has an unknown key 'extra'"),
    ],
)
def test_lambda_p_from_dict_names_the_wrong_field(path, value, message):
    with pytest.raises(ValueError, match=f"^λ/p study result: {message}"):
        LambdaPResult.from_dict(_set(_lambda_p(), path, value))


@pytest.mark.parametrize(
    "path,value,message",
    [
        ("alpha/table/0/L_e_full", "0.1", r"alpha.table\[0\].L_e_full must be a number, got '0.1'"),
        ("beta/table/1/alpha", 0.5, r"beta.table\[1\] has an unknown key 'alpha'"),
        ("alpha/settings/kind", "beta", "alpha.settings.kind must be 'alpha', got 'beta'"),
        ("beta/cached", 1, "beta.cached must be a bool, got 1"),
        ("alpha/fingerprint", None, "alpha.fingerprint must be a string"),
        ("alpha/table", None, "alpha.table must be a list"),
        ("beta", ..., "the result has no 'beta'"),
        ("cached", [], r"cached is \[\], the parts' are \['alpha'\]"),
        ("train_wall_time_s", 1.0, "train_wall_time_s is 1.0, the sum of the parts' is 6.75"),
        ("evaluated_on", "full set", "evaluated_on is not alpha.evaluated_on"),
        ("settings", None, "settings must be a dict"),
        ("wall_time_s", True, "wall_time_s must be a number, got True"),
    ],
)
def test_data_quality_from_dict_names_the_wrong_field(path, value, message):
    with pytest.raises(ValueError, match=f"^data-quality study result: {message}"):
        DataQualityResult.from_dict(_set(_data_quality(), path, value))


@pytest.mark.parametrize(
    "path,value,message",
    [
        ("metrics/lnn/t_error_exceeds_0.1", "never", "metrics.lnn.t_error_exceeds_0.1 must be a number or null"),
        ("metrics/lnn/train_force_error", None, "metrics.lnn.train_force_error must be a number, got None"),
        ("metrics/blackbox", ..., "metrics must have the keys nnphd, lnn, blackbox in that order"),
        ("train_time_s/nnphd", None, "train_time_s.nnphd must be a number"),
        ("train_time_s", [1.0], "train_time_s must be an object, got list"),
        ("energy_balance/rollout_finite", 1, "energy_balance.rollout_finite must be a bool, got 1"),
        ("decomposition/what", 3, "decomposition.what must be a string"),
        ("truth/energy_loss", ..., "truth has no 'energy_loss'"),
        ("lnn_energy_constancy/extra", 0.0, "lnn_energy_constancy has an unknown key 'extra'"),
        ("experiment", None, "experiment must be a string"),
        ("claims", {}, "claims must be a list"),
    ],
)
def test_prediction_from_dict_names_the_wrong_field(path, value, message):
    with pytest.raises(ValueError, match=f"^prediction result: {message}"):
        PredictionResult.from_dict(_set(_prediction(), path, value))


@pytest.mark.parametrize("cls,_make", CASES)
def test_from_dict_refuses_a_non_object_and_names_where(cls, _make):
    with pytest.raises(ValueError, match="^out/results.json: the result must be an object, got list"):
        cls.from_dict([], where="out/results.json")


def test_write_results_writes_to_dict_with_the_wall_time(tmp_path, monkeypatch):
    """wall_time_s is the clock after the figures are drawn less t0 (a stand-in clock: 995.0 until the figure is
    drawn, then 1000.25)."""
    res = DataQualityResult.from_dict(_data_quality())
    now = [995.0]
    monkeypatch.setattr(time, "perf_counter", lambda: now[0])
    drawn = []

    def draw(d):
        drawn.append(d)
        now[0] = 1000.25
        return _figure()

    done = write_results(tmp_path, res, {"f.png": draw}, 990.0)
    monkeypatch.undo()
    assert drawn == [res.to_dict()] and (tmp_path / "f.png").stat().st_size > 0
    assert done is not res and res.wall_time_s == 7.5 and done.wall_time_s == 1000.25 - 990.0
    assert (tmp_path / "results.json").read_text() == _dump(done.to_dict()) + "\n"
    assert write_results(None, res) is res


def _figure():
    from nnphd.io.results import subplots

    fig, ax = subplots()
    ax.plot([0, 1], [0, 1])
    return fig


def test_exported_lazily_without_jax():
    assert nnphd.LambdaPResult is LambdaPResult and nnphd.DataQualityResult is DataQualityResult
    assert nnphd.PredictionResult is PredictionResult
    assert {"LambdaPResult", "DataQualityResult", "PredictionResult"} <= set(nnphd.__all__)
    code = "import sys, nnphd; nnphd.LambdaPResult, nnphd.DataQualityResult, nnphd.PredictionResult; print('jax' in sys.modules)"
    assert (
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
        == "False"
    )
