"""The shared objective contract: counting, budget, best-so-far trace, validation."""

import numpy as np
import pytest

from replication.optim.objective import BudgetExhausted, Objective


def sphere(X):
    return (np.asarray(X) ** 2).sum(axis=1)


def test_counts_every_row_and_records_improvements_in_order():
    objective = Objective(sphere, [-1, -1], [1, 1])
    objective.evaluate([[0.5, 0.5], [0.1, 0.0], [0.9, 0.9]])
    objective.evaluate([[0.0, 0.01]])
    assert objective.n_evals == 4
    assert objective.trace.evals == [1, 2, 4]
    assert objective.trace.best_at(3) == pytest.approx(0.01)
    assert objective.trace.best_at(0) == np.inf
    assert objective.trace.first_eval_where(lambda x: abs(x[0]) < 0.2) == 2


def test_budget_truncates_the_crossing_batch_then_stops():
    objective = Objective(sphere, [-1], [1], budget=3)
    values = objective.evaluate(np.zeros((5, 1)) + 0.5)
    assert objective.n_evals == 3
    assert np.isinf(values[3:]).all() and np.isfinite(values[:3]).all()
    with pytest.raises(BudgetExhausted):
        objective.evaluate([[0.1]])


def test_residuals_are_counted_like_values():
    objective = Objective(sphere, [-1, -1], [1, 1], residuals=lambda X: np.asarray(X))
    residuals = objective.evaluate_residuals([[0.3, 0.4]])
    assert residuals.shape == (1, 2)
    assert objective.n_evals == 1 and objective.best_value == pytest.approx(0.25)


def test_non_finite_values_count_as_inf():
    objective = Objective(lambda X: np.full(len(X), np.nan), [0], [1])
    assert np.isinf(objective.evaluate([[0.5]])).all()
    assert objective.best_point is None


def test_bounds_low_not_below_high_are_refused_with_the_variable():
    with pytest.raises(ValueError, match="variable 1: low=2.0 >= high=1.0"):
        Objective(sphere, [0, 2], [1, 1])


def test_shape_mismatch_is_refused():
    with pytest.raises(ValueError, match=r"expected \(pop, 2\)"):
        Objective(sphere, [0, 0], [1, 1]).evaluate([[0.1, 0.2, 0.3]])
