"""The entry point for other code: identify the cloth parameters of any trajectory.

The paper's EA (:mod:`.ea`), the structured identifier (:mod:`.structured`) or a pymoo or
scipy baseline on the problem every identifier shares (:mod:`.problem`), through one
solver table (:data:`SOLVERS`) that the baselines study uses too.
"""

from __future__ import annotations

import numpy as np
from omegaconf import OmegaConf

from replication.cloth.identify import problem
from replication.cloth.identify.ea import EASettings, PaperEA
from replication.cloth.identify.structured import check_settings as check_structured
from replication.cloth.identify.structured import structured_identify
from replication.errors import InputError, check
from replication.optim.scipy_adapters import run_least_squares
from replication.provenance import PROJECT_ROOT

DEFAULT_BOUNDS = {"rest": [0.8, 1.2], "K": [0.1, 10.0], "tau": [0.01, 1.0]}
STRUCTURED_CONFIG = "configs/structured/default.yaml"   # the structured identifier's defaults


def default_structured():
    """The structured identifier's settings from :data:`STRUCTURED_CONFIG` (the config
    group every experiment takes them from; the code keeps no copy)."""
    return OmegaConf.to_container(OmegaConf.load(PROJECT_ROOT / STRUCTURED_CONFIG))


def _paper_ea(objective, trajectory, space, *, rng, seed, settings):
    ea_settings = EASettings.from_config(settings["ea"])
    initial = problem.random_population(space, ea_settings.pop_size, rng,
                                        rest_spread=settings["rest_spread"])
    ea = PaperEA(objective, ea_settings, rng, initial).run()
    return {"population": ea.X.tolist(), "population_cost": ea.F.tolist(),
            "history": ea.history}


def _structured(objective, trajectory, space, *, rng, seed, settings):
    best, info = structured_identify(trajectory, objective, space, rng=rng, settings=settings)
    info["population"] = [best.tolist()]
    return info


def _pymoo(objective, trajectory, space, *, rng, seed, settings):
    # pymoo is imported by the runs that use it (it takes about a second to import)
    from replication.optim.pymoo_adapters import run_pymoo

    return run_pymoo(objective, settings["algorithm"], seed=seed,
                     options=settings.get("options"))


def _least_squares(objective, trajectory, space, *, rng, seed, settings):
    return run_least_squares(objective, rng=rng, options=settings.get("options"))


# the one solver table: every identifier of the suite, by kind, on a counted Objective
SOLVERS = {"paper_ea": _paper_ea, "structured": _structured, "pymoo": _pymoo,
           "least_squares": _least_squares}


def check_solver(kind, settings):
    """Refuse an unknown ``kind`` or a pymoo algorithm or paper-EA settings that cannot run."""
    check(kind in SOLVERS, f"method={kind!r}: expected one of {', '.join(SOLVERS)}")
    if kind == "pymoo":
        from replication.optim.pymoo_adapters import ALGORITHMS

        check(settings.get("algorithm") in ALGORITHMS,
              f"algorithm={settings.get('algorithm')!r}; expected one of "
              f"{', '.join(ALGORITHMS)}")
    if kind == "paper_ea":
        EASettings.from_config(settings["ea"])
    if kind == "structured":
        check_structured(settings)


def solve(kind, objective, trajectory, space, *, rng, seed=None, settings):
    """Run the identifier ``kind`` (a key of :data:`SOLVERS`) on ``objective``.

    Every cost evaluation goes through ``objective`` (counted, budgeted, traced), so the
    answer is ``objective.best_point``.

    Parameters
    ----------
    kind : "paper_ea", "structured", "pymoo" or "least_squares"
    objective : Objective
        Over ``space``; with residuals for ``least_squares``.
    trajectory : Trajectory
    space : SearchSpace
    rng : np.random.Generator
    seed : int, optional
        pymoo's seed.
    settings : dict
        ``paper_ea``: ``ea`` (EASettings) and ``rest_spread``; ``structured``: see
        :func:`~replication.cloth.identify.structured.structured_identify`; ``pymoo``:
        ``algorithm`` and ``options``; ``least_squares``: ``options``.

    Returns
    -------
    info : dict
        What the identifier reports of its run.
    """
    check_solver(kind, settings)
    return SOLVERS[kind](objective, trajectory, space, rng=rng, seed=seed, settings=settings)


def identify(trajectory, *, model="5", rng=None, budget=None, method="structured",
             cost=None, bounds=None, settings=None):
    """Identify the cloth parameters of any trajectory (the entry point for other code).

    Parameters
    ----------
    trajectory : Trajectory
        Any trajectory (``replication.cloth.io.read_trajectory``, or one made in memory,
        checked as the reader checks a file); ``meta`` is not used to identify (only its
        ``true_params``, when present, is checked).
    model : "5" or "18"
        The paper's simplified model ``(l01, l23, l45, K, tau)`` or 18 parameters
        ``(rest_0..5, k_0..5, tau_0..5)``.
    rng : np.random.Generator, int or None
    budget : int or None
        Maximum number of cost evaluations (required by ``pymoo`` and ``least_squares``).
    method : "structured", "paper_ea", "pymoo" or "least_squares"
    cost : dict, optional
        Cost settings (``kind``: "small", "full" or "frames", ...); default the small cost.
    bounds : dict, optional
        ``rest`` (factors on observed lengths), ``K``, ``tau``; default
        :data:`DEFAULT_BOUNDS`.
    settings : dict, optional
        Method settings (see :func:`solve`); default for ``structured``
        :func:`default_structured`, for ``paper_ea`` the paper's rates with rest spread 0.1.

    Returns
    -------
    best_vector : (5,) or (18,) ndarray
    cost : float
    info : dict
        ``n_evals``, ``trace``, ``population`` (paper EA, best first), ``diagnostics``
        (:func:`~replication.cloth.identify.problem.diagnose`: taus the data do not
        determine, estimated noise, misfit), ``warnings`` (the diagnostics a user should
        read before the answer, as sentences), method details.

    Raises
    ------
    InputError
        A ``trajectory`` that is not a :class:`~replication.cloth.io.Trajectory` or fails
        the reader's checks (:func:`~replication.cloth.io.check_trajectory`), a
        ``budget`` that is not a positive integer, an unknown ``model`` or ``method``.
    """
    from replication.cloth.io import Trajectory, check_trajectory

    check(isinstance(trajectory, Trajectory),
          f"trajectory: a {type(trajectory).__name__}; expected a Trajectory (read a file "
          "with replication.cloth.io.read_trajectory(path), which also validates it)")
    trajectory = check_trajectory(trajectory)   # one made in memory is checked as a file is
    check(str(model) in problem.MODELS, f"model={model!r}: expected '5' or '18'")
    model = str(model)
    check(budget is None or (isinstance(budget, (int, np.integer))
                             and not isinstance(budget, bool) and budget >= 1),
          f"budget={budget!r}: expected an integer >= 1 (cost evaluations) or None")
    if method not in SOLVERS:
        raise InputError(f"method={method!r}: expected one of {', '.join(SOLVERS)}")
    if method in ("pymoo", "least_squares") and budget is None:
        raise InputError(f"method={method!r} runs until its budget is spent: give budget= "
                         "(cost evaluations)")
    rng = np.random.default_rng(rng)
    if settings is None:
        settings = (default_structured() if method == "structured"
                    else {"ea": {}, "rest_spread": 0.1})
    seed = int(rng.integers(2**31)) if method == "pymoo" else None
    cost_fn = problem.cost_from_config(trajectory, cost or {"kind": "small"})
    space = problem.search_space(trajectory, bounds or DEFAULT_BOUNDS, model=model)
    objective = problem.cloth_objective(cost_fn, space, budget=budget,
                                        with_residuals=method == "least_squares")
    info = solve(method, objective, trajectory, space, rng=rng, seed=seed, settings=settings)
    info["n_evals"] = objective.n_evals
    info["trace"] = objective.summary()["trace"]
    best = np.asarray(problem.finite_best(objective), float)
    info["diagnostics"] = problem.diagnose(cost_fn, best, space)
    info["warnings"] = problem.diagnostic_warnings(info["diagnostics"], best, space.names)
    return best, float(objective.best_value), info
