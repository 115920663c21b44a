"""pymoo 0.6.2 optimisers on an :class:`~replication.optim.objective.Objective`.

Every algorithm sees the objective's box bounds and its batched ``evaluate``; evaluations
are counted by the objective, not by pymoo (pymoo budgets overshoot, docs/pitfalls.md).
Algorithms that stop on their own tolerances before the budget is spent are restarted
from a new random point with a new seed until the budget is spent, so that every
optimiser uses the same number of evaluations. ``PatternSearch`` is not offered: it
ignores ``seed`` and is not reproducible (docs/pitfalls.md).
"""

from __future__ import annotations

import numpy as np
from pymoo.algorithms.soo.nonconvex.cmaes import CMAES
from pymoo.algorithms.soo.nonconvex.de import DE
from pymoo.algorithms.soo.nonconvex.ga import GA
from pymoo.algorithms.soo.nonconvex.nelder import NelderAndMeadTermination, NelderMead
from pymoo.algorithms.soo.nonconvex.pso import PSO
from pymoo.core.callback import Callback
from pymoo.core.problem import Problem
from pymoo.optimize import minimize

from replication.optim.objective import BudgetExhausted

ALGORITHMS = ("ga", "de", "cmaes", "pso", "nelder_mead")
WORST_COST = 1e300  # what pymoo sees instead of an infinite cost
_NEEDS_X0 = {"cmaes", "nelder_mead"}


class BatchedProblem(Problem):
    """A pymoo problem whose vectorised evaluation is ``objective.evaluate``."""

    def __init__(self, objective):
        super().__init__(n_var=objective.n_var, n_obj=1, xl=objective.lower,
                         xu=objective.upper)
        self.objective = objective

    def _evaluate(self, X, out, *args, **kwargs):
        # an infinite cost (a simulation that blew up) reaches pymoo as the largest cost it
        # can rank without arithmetic failing: Nelder-Mead's termination subtracts costs,
        # and inf - inf = NaN fails its "Invalid progress" check. The objective itself
        # (its count and trace) keeps inf.
        out["F"] = np.minimum(self.objective.evaluate(X), WORST_COST)[:, None]


class _GenerationCount(Callback):
    """Counts generations (progress is read from the objective's trace, not pymoo history)."""

    def __init__(self):
        super().__init__()
        self.generations = 0

    def notify(self, algorithm):
        self.generations += 1


def make_algorithm(name, *, x0=None, options=None):
    """A pymoo algorithm by ``name`` (one of :data:`ALGORITHMS`) with ``options``.

    ``x0`` : (n_var,) start point for CMA-ES and Nelder-Mead (they otherwise spend about
    20 evaluations sampling one).

    Parameters
    ----------
    name : str
    x0 : (n_var,) ndarray, optional
    options : dict, optional
        Keyword arguments of the pymoo algorithm.
    """
    options = dict(options or {})
    if name == "ga":
        return GA(**options)
    if name == "de":
        return DE(**options)
    if name == "pso":
        return PSO(**options)
    if name == "cmaes":
        return CMAES(x0=x0, **options)
    if name == "nelder_mead":
        return NelderMead(x0=x0, **options)
    raise ValueError(f"algorithm {name!r}: expected one of {', '.join(ALGORITHMS)}")


def _termination(name, budget, x_tol):
    """pymoo termination of one local run. Nelder-Mead stops when its simplex has shrunk
    below ``x_tol`` of the bounds (its default also has an absolute ``f_tol`` of 1e-6,
    which costs of order 1e-6 meet at once); the others run until the budget is spent
    (their defaults are absolute cost tolerances as well). The budget itself is enforced
    by the objective."""
    if name == "nelder_mead":
        return NelderAndMeadTermination(x_tol=x_tol, f_tol=0.0)
    return ("n_eval", budget + 1_000_000)


def run_pymoo(objective, name, *, seed, options=None, max_restarts=10_000, x_tol=1e-8):
    """Minimise ``objective`` with pymoo algorithm ``name`` until its budget is spent.

    Parameters
    ----------
    objective : Objective
        Must have a budget.
    name : str
        One of :data:`ALGORITHMS`.
    seed : int
        Seeds pymoo (``minimize(seed=)``) and the start points; restarts draw new seeds
        from a generator made from it, so the same seed gives the same run.
    options : dict, optional
        Keyword arguments of the pymoo algorithm (e.g. ``pop_size``, ``sigma``).
    x_tol : float
        Nelder-Mead restarts when its simplex is smaller than this fraction of the bounds.

    Returns
    -------
    dict with ``restarts`` and ``generations``; the result itself is in ``objective``.
    """
    if objective.budget is None:
        raise ValueError("run_pymoo needs an objective with a budget")
    if seed is None:
        raise ValueError("seed=None: pymoo runs must be seeded to be reproducible")
    rng = np.random.default_rng(seed)
    restarts, generations = 0, 0
    while objective.remaining > 0 and restarts < max_restarts:
        run_seed = int(rng.integers(2**31 - 1))
        x0 = None
        if name in _NEEDS_X0:
            x0 = objective.lower + rng.random(objective.n_var) * (objective.upper
                                                                    - objective.lower)
        algorithm = make_algorithm(name, x0=x0, options=options)
        counter = _GenerationCount()
        try:
            minimize(BatchedProblem(objective), algorithm,
                     _termination(name, objective.remaining, x_tol), seed=run_seed,
                     callback=counter, verbose=False)
        except BudgetExhausted:
            pass
        generations += counter.generations
        restarts += 1
    return {"restarts": restarts - 1, "generations": generations}
