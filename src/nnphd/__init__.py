"""nnphd — Neural New-Physics Detector.

Splits a force field q̈ = f(q, q̇, t) into a conservative part learned by a Lagrangian neural network (LNN)
and the smallest non-conservative remainder learned by a free MLP (the UAN), after Liu et al.,
"Machine-Learning Non-Conservative Dynamics for New-Physics Detection".

    import nnphd
    model = nnphd.NNPhD(seed=0).fit(nnphd.Trajectories(t, q, traj=ids, names=["x"]))

Importing nnphd changes nothing in your session (JAX's float64 switch, XLA_FLAGS, the matplotlib backend): the
API computes in float64 inside its own calls. :func:`configure` sets the process-wide settings the command line and
the tests use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

# the process-wide settings (configure) live in a module of the lowest layer; re-exported here
from nnphd._config import COMPILE_CACHE_ENV as COMPILE_CACHE_ENV
from nnphd._config import COMPILE_CACHE_MAX_BYTES as COMPILE_CACHE_MAX_BYTES
from nnphd._config import ONE_THREAD_FLAGS as ONE_THREAD_FLAGS
from nnphd._config import XLA_FLAG as XLA_FLAG
from nnphd._config import CompileCacheWarning as CompileCacheWarning
from nnphd._config import compile_cache_dir as compile_cache_dir
from nnphd._config import compile_cache_problem as compile_cache_problem
from nnphd._config import configure as configure
from nnphd._config import default_compile_cache as default_compile_cache
from nnphd._config import mapped_regions as mapped_regions
from nnphd._config import release_compiled_if_crowded as release_compiled_if_crowded

if TYPE_CHECKING:  # what __getattr__ loads on first use, visible to type checkers and the API reference (mkdocs)
    from nnphd._extras import MissingExtra
    from nnphd.api import DetectResult, Law, NNPhD, Status, Trajectories, Verdict, load, read_report
    from nnphd.io.errors import DataError
    from nnphd.paper.study_results import DataQualityResult, LambdaPResult, PredictionResult
    from nnphd.paper.sweep_result import SweepResult
    from nnphd.user.strategies import (
        AutoDerivatives,
        DerivativeEstimate,
        DerivativeEstimator,
        Derivatives,
        Family,
        LawLibrary,
        LocalPolynomial,
        SavitzkyGolay,
        SmoothingSpline,
    )

__version__ = "0.1.0"

__all__ = [
    "AutoDerivatives",
    "DataError",
    "DataQualityResult",
    "DerivativeEstimate",
    "DerivativeEstimator",
    "Derivatives",
    "DetectResult",
    "Family",
    "LambdaPResult",
    "Law",
    "LawLibrary",
    "LocalPolynomial",
    "MissingExtra",
    "NNPhD",
    "PredictionResult",
    "SavitzkyGolay",
    "SmoothingSpline",
    "Status",
    "SweepResult",
    "Trajectories",
    "Verdict",
    "__version__",
    "configure",
    "load",
    "read_report",
]
_API = ("DetectResult", "Law", "NNPhD", "Status", "Trajectories", "Verdict", "load", "read_report")
_STUDY_RESULTS = ("DataQualityResult", "LambdaPResult", "PredictionResult")  # the paper's studies' typed results
_STRATEGIES = (  # NNPhD's strategy objects (how q̇, q̈ are estimated; which laws) and what they hold
    "AutoDerivatives",
    "DerivativeEstimate",
    "DerivativeEstimator",
    "Derivatives",
    "Family",
    "LawLibrary",
    "LocalPolynomial",
    "SavitzkyGolay",
    "SmoothingSpline",
)


def __getattr__(name: str):  # the API loads on first use, so `import nnphd` stays light and inert
    if name == "DataError":  # a data file or array nnphd cannot use (a ValueError, one line)
        from nnphd.io.errors import DataError

        return DataError
    if name == "MissingExtra":  # an optional extra (nnphd[astro], [symbolic]) is not installed (an ImportError)
        from nnphd._extras import MissingExtra

        return MissingExtra
    if name in _API:
        from nnphd import api

        return getattr(api, name)
    if name in _STRATEGIES:
        from nnphd.user import strategies

        return getattr(strategies, name)
    if name == "SweepResult":  # the paper's λ-sweep result (nnphd.paper.sweep.run_sweep)
        from nnphd.paper.sweep_result import SweepResult

        return SweepResult
    if name in _STUDY_RESULTS:  # what lambda_p_study, data_quality_study, run_prediction return (no JAX)
        from nnphd.paper import study_results

        return getattr(study_results, name)
    raise AttributeError(f"module 'nnphd' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
