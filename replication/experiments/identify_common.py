"""Shared pieces of the identification experiments: data, validation, one run, scoring.

Every experiment validates its whole config against its data (bounds, EA rates, cost
frames) before it computes or writes anything.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from replication.cloth.identify import EASettings, PaperEA, problem
from replication.cloth.io import read_trajectory
from replication.errors import check


@dataclass
class Case:
    """One trajectory to identify: label, data, cost, search space, truth (or None)."""

    label: str
    path: str
    trajectory: object
    cost: object
    space: problem.SearchSpace
    truth: np.ndarray | None


def data_files(config):
    """``{label: path}``: ``data.path`` if given, else the config's ``references``."""
    path = (config.get("data") or {}).get("path")
    if path is not None:
        return {Path(path).stem: str(path)}
    references = config.get("references") or {}
    check(len(references) > 0, "references: expected at least one trajectory file "
                               "(or data.path=FILE)")
    return {str(label): str(file) for label, file in references.items()}


def load_cases(config, *, model="5", cost=None):
    """Read and validate every data file of ``config`` into :class:`Case` objects.

    Parameters
    ----------
    config : dict
        ``data.path`` or ``references``, ``cost``, ``bounds``.
    model : "5" or "18"
    cost : dict, optional
        Cost settings instead of ``config["cost"]``.
    """
    cases = []
    for label, path in data_files(config).items():
        trajectory = read_trajectory(path)
        cost_fn = problem.cost_from_config(trajectory, cost or config["cost"])
        space = problem.search_space(trajectory, config["bounds"], model=model)
        cases.append(Case(label, path, trajectory, cost_fn, space,
                          problem.truth_vector(trajectory, model)))
    return cases


def check_common(config):
    """Validate the settings shared by identification experiments; returns EASettings."""
    settings = EASettings.from_config(config["ea"])
    n_seeds = int(config.get("n_seeds", 1))
    check(n_seeds >= 1, f"n_seeds={n_seeds}: expected at least 1")
    rtol = float(config.get("success_rtol", 0.01))
    check(rtol > 0, f"success_rtol={rtol}: expected > 0")
    spread = float(config["init"]["rest_spread"])
    check(0 <= spread < 1, f"init.rest_spread={spread}: expected a fraction in [0, 1)")
    return settings


def run_rng(seed, *keys):
    """The generator of one run: from the config seed and the run's position.

    Parameters
    ----------
    seed : int
        The config's seed.
    *keys : int
        The run's indices (case, optimiser, seed index...).
    """
    return np.random.default_rng([int(seed), *[int(k) for k in keys]])


def outcome(vector, truth, rtol):
    """"truth" (all within ``rtol``), "inactive-constraint valley" (tau above the truth by
    more than 20%: the constraint is switched off) or "elsewhere"; None without truth.

    Parameters
    ----------
    vector : (n_var,) ndarray
    truth : (n_var,) ndarray or None
    rtol : float
    """
    if truth is None:
        return None
    if problem.is_success(vector, truth, rtol):
        return "truth"
    n_tau = 6 if len(truth) == 18 else 1
    if np.all(vector[-n_tau:] > 1.2 * truth[-n_tau:]):
        return "inactive-constraint valley"
    return "elsewhere"


def paper_ea_run(case, settings, rng, *, rest_spread, budget=None):
    """One run of the paper's EA on ``case``; returns (PaperEA, Objective).

    Parameters
    ----------
    case : Case
    settings : EASettings
    rng : np.random.Generator
    rest_spread : float
    budget : int, optional
    """
    objective = problem.cloth_objective(case.cost, case.space, budget=budget)
    initial = problem.random_population(case.space, settings.pop_size, rng,
                                        rest_spread=rest_spread)
    return PaperEA(objective, settings, rng, initial).run(), objective


def score(vector, case, rtol):
    """Errors and outcome of an answer on ``case`` (empty without a known truth).

    Parameters
    ----------
    vector : (n_var,) array_like
    case : Case
    rtol : float
    """
    if case.truth is None:
        return {}
    errors = problem.relative_errors(vector, case.truth)
    return {"relative_errors": dict(zip(case.space.names, errors.tolist())),
            "success": problem.is_success(vector, case.truth, rtol),
            "outcome": outcome(np.asarray(vector), case.truth, rtol)}


def population_rows(X, F, names):
    """Final population as named rows with their cost, best first.

    Parameters
    ----------
    X : (pop, n_var) ndarray
    F : (pop,) ndarray
    names : sequence of str
    """
    return [problem.named(x, names, f) for x, f in zip(X, F)]
