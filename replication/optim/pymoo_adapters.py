"""pymoo 0.6.2 optimisers on an :class:`~replication.optim.objective.Objective`.

Every algorithm sees the objective's box bounds and its batched ``evaluate``; evaluations
are counted by the objective, not by pymoo (pymoo budgets overshoot, docs/pitfalls.md).
Algorithms that stop on their own tolerances before the budget is spent are restarted
from a new random point with a new seed until the budget is spent, so that every
optimiser uses the same number of evaluations. ``PatternSearch`` is not offered: it
ignores ``seed`` and is not reproducible (docs/pitfalls.md).

:func:`run_pymoo` drives each run itself (``setup``, then ``next`` while ``has_next``),
as ``pymoo.optimize.minimize`` does, but leaner: an evaluator that writes only what the
algorithms read (the costs, and the constraint violation 0 at once instead of pymoo
computing it per individual), the optimum found by one ``argmin`` instead of pymoo's
feasibility and non-dominance filter, and Nelder-Mead's termination test without pymoo's
generic helpers; no callback, display or result object.
Each is exact for :class:`BatchedProblem` (one objective, no constraints), so runs are
bit-identical to ``minimize``'s (tests/test_pymoo_lean.py compares them).
"""

from __future__ import annotations

import copy

import numpy as np
from pymoo.algorithms.soo.nonconvex.cmaes import CMAES
from pymoo.algorithms.soo.nonconvex.de import DE
from pymoo.algorithms.soo.nonconvex.ga import GA
from pymoo.algorithms.soo.nonconvex.nelder import NelderAndMeadTermination, NelderMead
from pymoo.algorithms.soo.nonconvex.pso import PSO
from pymoo.core.evaluator import Evaluator
from pymoo.core.individual import Individual
from pymoo.core.population import Population
from pymoo.core.problem import Problem

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


# ---------------------------------------------------------------------------------------
# The lean pieces. Each replaces generic pymoo bookkeeping by what it amounts to on a
# BatchedProblem: one objective and no constraints, so every individual's constraint
# violation CV is 0 (pymoo computes it from the empty G and H) and every one is feasible.
# ---------------------------------------------------------------------------------------

_EVALUATED = frozenset(("F", "G", "H"))  # what pymoo's Evaluator marks as evaluated


class _LeanEvaluator(Evaluator):
    """pymoo's ``Evaluator`` for a :class:`BatchedProblem` without its generic path.

    Like pymoo's, it evaluates only the individuals not yet evaluated (in order, as one
    batch), counts them in ``n_eval`` and marks them evaluated. It writes ``F``, and the
    constraint violation ``CV`` pymoo would otherwise compute for each individual when an
    algorithm first reads it (``Individual.CV`` from ``G`` and ``H``): without constraints
    these are empty arrays (the full evaluator writes them so; they are also an
    individual's defaults), whose violation is ``[0.0]``.
    """

    def eval(self, problem, pop, algorithm=None):
        # (the one keyword pymoo's algorithms pass; any other is a TypeError, not ignored)
        todo = [ind for ind in ([pop] if isinstance(pop, Individual) else pop)
                if not _EVALUATED <= ind.evaluated]
        if todo:  # (an empty call would raise BudgetExhausted once the budget is spent)
            out = {}
            problem._evaluate(np.array([ind.X for ind in todo]), out)
            for ind, f in zip(todo, out["F"]):
                ind.F = f.copy()  # an own array per individual, as Population.set gives
                ind.CV = np.zeros(1)
                ind.evaluated.update(_EVALUATED)
        self.n_eval += len(todo)
        return pop


def _first_best(pop):
    """``pymoo.util.optimum.filter_optimum(pop, least_infeasible=True)`` when every
    individual is feasible: the first individual of least ``F`` (``argmin`` takes the first
    of ties, as pymoo's does), as a one-individual population; ``None`` for no population."""
    if pop is None or len(pop) == 0:
        return None
    return Population.create(pop[np.argmin(np.array([ind.F[0] for ind in pop]))])


class _FirstBestOptimum:
    """Mixin: pymoo's default ``_set_optimum`` (the best of ``pop``) via :func:`_first_best`.

    PSO reads this optimum as its social best, so it must be the very same individual.
    """

    def _set_optimum(self):
        self.opt = _first_best(self.pop)


class _FirstBestOfOptAndPop:
    """Mixin: CMA-ES's ``_set_optimum`` (the best of the old optimum followed by ``pop``,
    so that the old optimum wins ties) via :func:`_first_best`."""

    def _set_optimum(self):
        pop = self.pop if self.opt is None else Population.merge(self.opt, self.pop)
        self.opt = _first_best(pop)


class _LeanGA(_FirstBestOptimum, GA):
    pass


class _LeanPSO(_FirstBestOptimum, PSO):
    pass


class _LeanNelderMead(_FirstBestOptimum, NelderMead):
    pass


class _LeanCMAES(_FirstBestOfOptAndPop, CMAES):
    pass


# DE keeps its own _set_optimum: a mask of the ranks it has just computed, already cheap
_LEAN_CLASSES = {"ga": _LeanGA, "de": DE, "cmaes": _LeanCMAES, "pso": _LeanPSO,
                 "nelder_mead": _LeanNelderMead}


class _NelderMeadTermination(NelderAndMeadTermination):
    """``NelderAndMeadTermination`` with the same arithmetic on the same arrays (so the same
    progress value and decision), without pymoo's ``Population.get``, ``vectorized_cdist``
    and a new ``np.triu_indices`` at every generation."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._upper = {}  # n -> np.triu_indices(n, 1)

    def _update(self, algorithm):
        pop, problem = algorithm.pop, algorithm.problem
        n = len(pop)
        if n <= 1:
            return 0.0
        X = np.array([ind.X for ind in pop])
        F = np.array([ind.F for ind in pop])

        f_delta = np.abs(F[1:] - F[0]).max()
        f_tol = 1 / (1 + (f_delta - self.f_tol))
        if problem.has_bounds():
            x_delta = np.abs((X[1:] - X[0]) / (problem.xu - problem.xl)).max()
        else:
            x_delta = np.abs(X[1:] - X[0]).max()
        x_tol = 1 / (1 + (x_delta - self.x_tol))

        # the simplex's edge lengths, computed exactly as vectorized_cdist does (every
        # pair, in the same array layout) so that they agree to the last bit
        if n not in self._upper:
            self._upper[n] = np.triu_indices(n, 1)
        D = np.sqrt(((np.repeat(X, n, axis=0) - np.tile(X, (n, 1))) ** 2).sum(axis=1))
        val = np.reshape(D, (n, n))[self._upper[n]]
        min_e, max_e = val.min(), val.max()
        is_degenerated = int(max_e < 1e-16 or min_e / max_e < 1e-16)

        max_iter = algorithm.n_iter / self.n_max_iter
        max_evals = algorithm.evaluator.n_eval / self.n_max_evals
        return max(f_tol, x_tol, max_iter, max_evals, is_degenerated)


def make_algorithm(name, *, x0=None, options=None):
    """A pymoo algorithm by ``name`` (one of :data:`ALGORITHMS`) with ``options``.

    Parameters
    ----------
    name : str
    x0 : (n_var,) ndarray, optional
        Start point for CMA-ES and Nelder-Mead (they otherwise spend about 20 evaluations
        sampling one); ignored by the others.
    options : dict, optional
        Keyword arguments of the pymoo algorithm.

    The algorithm is pymoo's with a cheaper optimum bookkeeping (:class:`_FirstBestOptimum`)
    that is exact only on problems with one objective and no constraints, such as
    :class:`BatchedProblem`.
    """
    options = dict(options or {})
    if name not in ALGORITHMS:
        raise ValueError(f"algorithm {name!r}: expected one of {', '.join(ALGORITHMS)}")
    cls = _LEAN_CLASSES[name]
    return cls(x0=x0, **options) if name in _NEEDS_X0 else cls(**options)


def _termination(name, budget, x_tol):
    """pymoo termination of one local run. Nelder-Mead stops when its simplex has shrunk
    below ``x_tol`` of the bounds (its default also has an absolute ``f_tol`` of 1e-6,
    which costs of order 1e-6 meet at once); the others run until the budget is spent
    (their defaults are absolute cost tolerances as well). The budget itself is enforced
    by the objective. (CMA-ES also passes the ``n_eval`` limit to cma as ``maxfevals``.)"""
    if name == "nelder_mead":
        return _NelderMeadTermination(x_tol=x_tol, f_tol=0.0)
    return ("n_eval", budget + 1_000_000)


def _run_once(problem, algorithm, termination, seed):
    """One local run of ``algorithm`` until it stops or the budget is spent, as
    ``pymoo.optimize.minimize(problem, algorithm, termination, seed=seed)`` runs it
    (without its result object); returns the number of generations completed."""
    # minimize runs a deep copy: it keeps the operator objects that pymoo's constructors
    # share between instances (mutable default arguments) apart from run to run
    algorithm = copy.deepcopy(algorithm)
    algorithm.setup(problem, termination=termination, seed=seed, verbose=False,
                    evaluator=_LeanEvaluator())
    try:
        while algorithm.has_next():
            algorithm.next()
    except BudgetExhausted:
        pass
    # n_iter is 1 from the first infill on and grows by one at the end of every completed
    # generation (Algorithm._post_advance, where a callback would be notified)
    return 0 if algorithm.n_iter is None else algorithm.n_iter - 1


def run_pymoo(objective, name, *, seed, options=None, max_restarts=10_000, x_tol=1e-8):
    """Minimise ``objective`` with pymoo algorithm ``name`` until its budget is spent.

    Parameters
    ----------
    objective : Objective
        Must have a budget.
    name : str
        One of :data:`ALGORITHMS`.
    seed : int
        Seeds pymoo (``Algorithm.setup(seed=)``) and the start points; restarts draw new
        seeds from a generator made from it, so the same seed gives the same run.
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
        generations += _run_once(BatchedProblem(objective), algorithm,
                                 _termination(name, objective.remaining, x_tol), run_seed)
        restarts += 1
    return {"restarts": restarts - 1, "generations": generations}
