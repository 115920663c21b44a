"""Every optimiser survives a cost that is infinite or NaN on part of the box.

A simulation that blows up gives an infinite cost; a NaN must never reach a ranking. The
objective here is a quadratic bowl on [0, 1]^2 with its minimum at ``CENTRE``, NaN where
``x0 > 0.7`` and inf where ``x1 < 0.1``: each optimiser, on a small budget, must end without
an exception, spend the budget, and return a finite best value at a point of the finite
region, and the objective's trace must never hold a NaN.

The segmentation's disc EA (``replication.motion.segment.disc_ea.DiscEA``) is not run here: it
computes its own cost from image data (``disc_cost``) and takes no objective.
"""

import numpy as np
import pytest

from replication.cloth.identify import EASettings, PaperEA
from replication.optim.objective import Objective
from replication.optim.pymoo_adapters import ALGORITHMS, run_pymoo
from replication.optim.scipy_adapters import run_least_squares

CENTRE = np.array([0.4, 0.5])
BUDGET = 300


def residuals(X):
    """Residuals ``X - CENTRE`` (pop, 2): NaN rows where x0 > 0.7, inf rows where x1 < 0.1."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    r = X - CENTRE
    r[X[:, 0] > 0.7] = np.nan
    r[X[:, 1] < 0.1] = np.inf
    return r


def value(X):
    return (residuals(X) ** 2).sum(axis=1)


def finite_region(x):
    return x[0] <= 0.7 and x[1] >= 0.1


def make_objective():
    return Objective(value, [0.0, 0.0], [1.0, 1.0], budget=BUDGET, residuals=residuals)


def check_run(objective):
    assert objective.n_evals == BUDGET
    assert np.isfinite(objective.best_value)
    assert finite_region(objective.best_point)
    values = np.asarray(objective.trace.values)
    assert values.size and not np.isnan(values).any()
    assert all(finite_region(np.asarray(p)) for p in objective.trace.points)


def test_the_objective_is_infinite_and_nan_where_it_should_be():
    X = np.array([[0.4, 0.5], [0.8, 0.5], [0.4, 0.05], [0.8, 0.05]])
    raw = value(X)
    assert raw[0] == 0.0 and np.isnan(raw[1]) and np.isinf(raw[2])
    assert np.isinf(make_objective().evaluate(X)[1:]).all()  # the objective maps NaN to inf


@pytest.mark.parametrize("name", ALGORITHMS)
def test_pymoo_algorithms_handle_infinite_and_nan_costs(name):
    objective = make_objective()
    run_pymoo(objective, name, seed=0)
    check_run(objective)


def test_least_squares_handles_infinite_and_nan_residuals():
    objective = make_objective()
    info = run_least_squares(objective, rng=0)
    check_run(objective)
    assert info["starts"] > 1  # starts in the infinite or NaN region are replaced


def test_paper_ea_handles_infinite_and_nan_costs():
    objective = make_objective()
    rng = np.random.default_rng(0)
    settings = EASettings(pop_size=20, generations=1000)  # the budget ends the run
    ea = PaperEA(objective, settings, rng, rng.random((settings.pop_size, 2))).run()
    check_run(objective)
    assert not np.isnan(ea.F).any()
    assert np.all(np.diff(ea.F) >= 0)  # the ranking is a plain sort: inf last, no NaN
    np.testing.assert_allclose(ea.X[0], objective.best_point)
