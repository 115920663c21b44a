"""The entry point for other code: identify the cloth parameters of any trajectory.

The paper's EA (:mod:`.ea`) or the structured identifier (:mod:`.structured`) on the
problem every identifier shares (:mod:`.problem`).
"""

from __future__ import annotations

import numpy as np

from replication.cloth.identify import problem
from replication.cloth.identify.ea import EASettings, PaperEA
from replication.cloth.identify.structured import structured_identify
from replication.errors import InputError

DEFAULT_BOUNDS = {"rest": [0.8, 1.2], "K": [0.1, 10.0], "tau": [0.01, 1.0]}
DEFAULT_STRUCTURED = {
    "regression": {"first": 1, "stride": 5},
    "tau_scan": {"n_grid": 100, "refine_evals": 40},
    "refine": {"box": 0.02, "ea": {"pop_size": 20, "generations": 10}},
}


def identify(trajectory, *, model="5", rng=None, budget=None, method="structured",
             cost=None, bounds=None, settings=None):
    """Identify the cloth parameters of any trajectory (the entry point for other code).

    Parameters
    ----------
    trajectory : Trajectory
        Any trajectory (``replication.cloth.io.read_trajectory``); ``meta`` is not used.
    model : "5" or "18"
        The paper's simplified model ``(l01, l23, l45, K, tau)`` or 18 parameters
        ``(rest_0..5, k_0..5, tau_0..5)``.
    rng : np.random.Generator, int or None
    budget : int or None
        Maximum number of cost evaluations.
    method : "structured" or "paper_ea"
    cost : dict, optional
        Cost settings (``kind``: "small", "full" or "frames", ...); default the small cost.
    bounds : dict, optional
        ``rest`` (factors on observed lengths), ``K``, ``tau``; default
        :data:`DEFAULT_BOUNDS`.
    settings : dict, optional
        Method settings (see ``configs/experiment/cloth_identify.yaml``).

    Returns
    -------
    best_vector : (5,) or (18,) ndarray
    cost : float
    info : dict
        ``n_evals``, ``population`` (paper EA, best first), method details.
    """
    rng = np.random.default_rng(rng)
    cost_fn = problem.cost_from_config(trajectory, cost or {"kind": "small"})
    space = problem.search_space(trajectory, bounds or DEFAULT_BOUNDS, model=model)
    objective = problem.cloth_objective(cost_fn, space, budget=budget)
    if method == "structured":
        best, info = structured_identify(trajectory, objective, space, rng=rng,
                                         settings=settings or DEFAULT_STRUCTURED)
        info["population"] = [best.tolist()]
    elif method == "paper_ea":
        settings = dict(settings or {"ea": {}, "rest_spread": 0.1})
        ea_settings = EASettings.from_config(settings["ea"])
        initial = problem.random_population(space, ea_settings.pop_size, rng,
                                            rest_spread=settings["rest_spread"])
        ea = PaperEA(objective, ea_settings, rng, initial).run()
        best = ea.X[0]
        info = {"population": ea.X.tolist(), "population_cost": ea.F.tolist(),
                "history": ea.history}
    else:
        raise InputError(f"method={method!r}: expected 'structured' or 'paper_ea'")
    info["n_evals"] = objective.n_evals
    info["trace"] = objective.summary()["trace"]
    if objective.best_point is not None:
        best = objective.best_point
    return np.asarray(best, float), float(objective.best_value), info

