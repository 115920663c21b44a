"""pymoo and scipy adapters: same seed gives the same run, budgets are exact."""

import numpy as np
import pytest

from replication.optim.objective import Objective
from replication.optim.pymoo_adapters import ALGORITHMS, run_pymoo
from replication.optim.scipy_adapters import run_least_squares

SHIFT = np.array([0.3, -0.2, 0.1])


def residuals(X):
    return np.asarray(X) - SHIFT


def value(X):
    return (residuals(X) ** 2).sum(axis=1)


def make(budget):
    return Objective(value, -np.ones(3), np.ones(3), budget=budget, residuals=residuals)


@pytest.mark.parametrize("name", ALGORITHMS)
def test_pymoo_same_seed_same_trace_and_exact_budget(name):
    runs = []
    for _ in range(2):
        objective = make(300)
        run_pymoo(objective, name, seed=7)
        runs.append(objective)
    assert runs[0].n_evals == 300
    assert runs[0].trace.evals == runs[1].trace.evals
    assert runs[0].trace.values == runs[1].trace.values
    other = make(300)
    run_pymoo(other, name, seed=8)
    assert other.trace.points != runs[0].trace.points


def test_pymoo_refuses_unknown_algorithm_and_missing_seed():
    with pytest.raises(ValueError, match="algorithm 'pattern'"):
        run_pymoo(make(10), "pattern", seed=0)
    with pytest.raises(ValueError, match="seed=None"):
        run_pymoo(make(10), "ga", seed=None)


def test_least_squares_same_rng_same_run_and_finds_the_minimum():
    runs = []
    for _ in range(2):
        objective = make(200)
        info = run_least_squares(objective, rng=3)
        runs.append(objective)
    assert runs[0].n_evals == 200 and info["starts"] >= 2
    assert runs[0].trace.values == runs[1].trace.values
    np.testing.assert_allclose(runs[0].best_point, SHIFT, atol=1e-6)
