"""``run_pymoo``'s lean driving of pymoo gives bit-identical runs to ``pymoo.optimize.minimize``.

:func:`reference_run_pymoo` is the implementation ``run_pymoo`` replaced: ``minimize`` per
restart with a generation-counting callback, pymoo's own evaluator, optimum and
Nelder-Mead termination. Both run every algorithm on a cheap 5-variable cost shaped like
the cloth problem's search space: a shifted Rosenbrock valley with ripples, rounded to
1e-4 so that costs tie (the optimum must pick the same individual among equals and
Nelder-Mead's simplex flattens and restarts), infinite where ``K > 9`` and NaN where
``tau < 0.02`` (so pymoo sees ties at ``WORST_COST`` too). The evaluated points' trace, the
evaluation count and the returned restarts and generations must be equal.
"""

import numpy as np
import pytest
from pymoo.algorithms.soo.nonconvex.cmaes import CMAES
from pymoo.algorithms.soo.nonconvex.de import DE
from pymoo.algorithms.soo.nonconvex.ga import GA
from pymoo.algorithms.soo.nonconvex.nelder import NelderAndMeadTermination, NelderMead
from pymoo.algorithms.soo.nonconvex.pso import PSO
from pymoo.core.callback import Callback
from pymoo.core.individual import Individual
from pymoo.core.population import Population
from pymoo.optimize import minimize
from pymoo.util.optimum import filter_optimum

from replication.optim import pymoo_adapters
from replication.optim.objective import BudgetExhausted, Objective
from replication.optim.pymoo_adapters import ALGORITHMS, BatchedProblem, run_pymoo

LOWER = np.array([0.8, 0.8, 0.8, 0.1, 0.01])
UPPER = np.array([1.2, 1.2, 1.2, 10.0, 1.0])
TRUTH = np.array([1.05, 0.95, 1.1, 3.0, 0.2])
OPTIONS = {"ga": None, "de": None, "cmaes": {"sigma": 0.3}, "pso": {"pop_size": 25},
           "nelder_mead": None}


def cost(X):
    """Rounded, rippled, shifted Rosenbrock; inf where K > 9, NaN where tau < 0.02."""
    u = 1.0 + 4.0 * (X - TRUTH) / (UPPER - LOWER)
    f = (100.0 * (u[:, 1:] - u[:, :-1] ** 2) ** 2 + (1.0 - u[:, :-1]) ** 2).sum(axis=1)
    f += 0.05 * (np.sin(25.0 * u) ** 2).sum(axis=1)
    f = np.round(f, 4)
    f[X[:, 3] > 9.0] = np.inf
    f[X[:, 4] < 0.02] = np.nan
    return f


def make(budget):
    return Objective(cost, LOWER, UPPER, budget=budget)


class _GenerationCount(Callback):
    def __init__(self):
        super().__init__()
        self.generations = 0

    def notify(self, algorithm):
        self.generations += 1


def reference_run_pymoo(objective, name, *, seed, options=None, max_restarts=10_000,
                        x_tol=1e-8):
    """``run_pymoo`` as it was: ``pymoo.optimize.minimize`` per restart."""
    rng = np.random.default_rng(seed)
    restarts, generations = 0, 0
    while objective.remaining > 0 and restarts < max_restarts:
        run_seed = int(rng.integers(2**31 - 1))
        x0 = None
        if name in ("cmaes", "nelder_mead"):
            x0 = objective.lower + rng.random(objective.n_var) * (objective.upper
                                                                    - objective.lower)
        kwargs = dict(options or {})
        algorithm = {"ga": GA, "de": DE, "pso": PSO}[name](**kwargs) if x0 is None else \
            {"cmaes": CMAES, "nelder_mead": NelderMead}[name](x0=x0, **kwargs)
        termination = (NelderAndMeadTermination(x_tol=x_tol, f_tol=0.0)
                       if name == "nelder_mead" else ("n_eval", objective.remaining + 1_000_000))
        counter = _GenerationCount()
        try:
            minimize(BatchedProblem(objective), algorithm, termination, seed=run_seed,
                     callback=counter, verbose=False)
        except BudgetExhausted:
            pass
        generations += counter.generations
        restarts += 1
    return {"restarts": restarts - 1, "generations": generations}


def both_runs(name, seed, budget, **kwargs):
    """(n_evals, trace evals, values, points, returned dict) of the lean and reference runs."""
    runs = []
    for run in (run_pymoo, reference_run_pymoo):
        objective = make(budget)
        info = run(objective, name, seed=seed, options=OPTIONS[name], **kwargs)
        runs.append((objective.n_evals, objective.trace.evals, objective.trace.values,
                     objective.trace.points, info))
    return runs


@pytest.mark.parametrize("name", ALGORITHMS)
def test_lean_runs_are_bit_identical_to_minimize(name):
    budget = {"nelder_mead": 1200, "cmaes": 1500}.get(name, 2000)
    restarts = 0
    for seed in (0, 1, 2):
        lean, reference = both_runs(name, seed, budget)
        assert lean == reference, f"{name}, seed {seed}"
        assert lean[0] == budget
        restarts += lean[4]["restarts"]
    if name in ("cmaes", "nelder_mead"):  # these stop on their own and restart here
        assert restarts > 0


@pytest.mark.parametrize("name", ALGORITHMS)
def test_lean_runs_are_bit_identical_on_tiny_budgets_and_few_restarts(name):
    # a first batch cut short by the budget (no generation completes), and a run that
    # ends on max_restarts before the budget is spent
    for budget in (1, 7, 130):
        lean, reference = both_runs(name, 3, budget)
        assert lean == reference, f"{name}, budget {budget}"
    lean, reference = both_runs(name, 4, 600, max_restarts=2, x_tol=1e-3)
    assert lean == reference
    if name == "nelder_mead":
        assert lean[0] < 600


def _population(F, X=None):
    X = np.arange(3.0 * len(F)).reshape(len(F), 3) if X is None else X
    pop = Population.new(X=X)
    pop.set("F", np.asarray(F, float)[:, None])
    return pop


def test_first_best_is_pymoos_optimum_with_ties():
    for F in ([3.0, 1.0, 2.0, 1.0], [1e300, 1e300], [5.0], [2.0, 0.0, 0.0, 0.0]):
        pop = _population(F)
        assert pymoo_adapters._first_best(pop)[0] is filter_optimum(pop, least_infeasible=True)[0]
    assert pymoo_adapters._first_best(Population.empty()) is None


def test_nelder_mead_termination_gives_pymoos_progress():
    class Algorithm:  # what the termination reads of an algorithm
        problem = BatchedProblem(make(10))
        n_iter = 12
        evaluator = pymoo_adapters._LeanEvaluator()

    rng = np.random.default_rng(5)
    simplices = [LOWER + rng.random((6, 5)) * (UPPER - LOWER) for _ in range(50)]
    simplices.append(np.repeat(TRUTH[None], 6, axis=0))                  # degenerate
    simplices.append(TRUTH + 1e-12 * rng.random((6, 5)))                 # tiny (x_tol)
    for X in simplices:
        # distinct costs, a flat simplex, all at WORST_COST, and f_delta below 1 + eps
        for F in (rng.random(6), np.full(6, 0.25), np.full(6, 1e300),
                  np.r_[0.0, np.full(5, 1e-17)]):
            Algorithm.pop = _population(F, X)
            for x_tol in (1e-8, 1e-3):
                ours = pymoo_adapters._NelderMeadTermination(x_tol=x_tol, f_tol=0.0)
                pymoos = NelderAndMeadTermination(x_tol=x_tol, f_tol=0.0)
                assert ours.update(Algorithm) == pymoos.update(Algorithm)
                assert ours.has_terminated() == pymoos.has_terminated()


def test_lean_evaluator_skips_evaluated_individuals_and_counts_like_pymoos():
    objective = make(100)
    problem = BatchedProblem(objective)
    evaluator = pymoo_adapters._LeanEvaluator()
    pop = Population.new(X=LOWER + np.linspace(0.1, 0.9, 4)[:, None] * (UPPER - LOWER))
    evaluator.eval(problem, pop[:2], algorithm=None)
    assert evaluator.n_eval == 2 and objective.n_evals == 2
    evaluator.eval(problem, pop, algorithm=None)          # only the last two are new
    assert evaluator.n_eval == 4 and objective.n_evals == 4
    single = Individual(X=TRUTH.copy())
    assert evaluator.eval(problem, single) is single and single.F.shape == (1,)
    for ind in [*pop, single]:
        assert ind.feas and ind.CV[0] == 0.0
        assert ind.F[0] == min(cost(ind.X[None])[0], pymoo_adapters.WORST_COST)
