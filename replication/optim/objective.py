"""The one objective contract shared by every optimiser (docs/extending.md).

``evaluate(X: (pop, n_var)) -> (pop,)``: every optimiser, the paper's EAs and every
baseline, scores the same batched function through an :class:`Objective`, which counts
evaluations one parameter vector at a time, enforces a budget and records the best-so-far
trace, so that "evaluations to success" and "cost at a fixed budget" mean the same thing
for all of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class BudgetExhausted(Exception):
    """Raised by :meth:`Objective.evaluate` when called after the budget is spent."""


@dataclass
class Trace:
    """Best-so-far record: one entry per improvement.

    ``evals[i]`` is the evaluation count (1-based) at which ``values[i]`` and ``points[i]``
    became the best so far.
    """

    evals: list = field(default_factory=list)
    values: list = field(default_factory=list)
    points: list = field(default_factory=list)

    def best_at(self, n_evals):
        """Best value after ``n_evals`` evaluations (``inf`` before the first one)."""
        index = np.searchsorted(np.asarray(self.evals), n_evals, side="right") - 1
        return float(self.values[index]) if index >= 0 else np.inf

    def point_at(self, n_evals):
        """Best point after ``n_evals`` evaluations, or ``None``."""
        index = np.searchsorted(np.asarray(self.evals), n_evals, side="right") - 1
        return np.asarray(self.points[index]) if index >= 0 else None

    def first_eval_where(self, predicate):
        """First evaluation count whose best point satisfies ``predicate(point)``, or None.

        The best point only changes at improvements, so checking those is exact.
        """
        for n_evals, point in zip(self.evals, self.points):
            if predicate(np.asarray(point)):
                return int(n_evals)
        return None


class Objective:
    """A counted, budgeted, batched objective.

    Parameters
    ----------
    fun : callable
        ``fun(X: (pop, n_var)) -> (pop,)``; non-finite values are treated as ``inf``.
    lower, upper : (n_var,) array_like
        Box bounds (the search space every optimiser is given).
    budget : int or None
        Maximum number of parameter vectors evaluated. A batch that crosses the budget is
        evaluated only up to it (the rows beyond get ``inf`` and are not counted); the next
        call raises :class:`BudgetExhausted`.
    residuals : callable, optional
        ``residuals(X: (pop, n_var)) -> (pop, m)`` with ``fun(X) == (residuals(X)**2).sum(1)``,
        for least-squares optimisers; counted exactly like ``fun``.
    names : sequence of str, optional
        Parameter names (for results).
    """

    def __init__(self, fun, lower, upper, *, budget=None, residuals=None, names=None):
        self.fun = fun
        self.residual_fun = residuals
        self.lower = np.asarray(lower, dtype=float).copy()
        self.upper = np.asarray(upper, dtype=float).copy()
        if self.lower.shape != self.upper.shape or self.lower.ndim != 1:
            raise ValueError(f"bounds of shapes {self.lower.shape} and {self.upper.shape}: "
                             "expected two (n_var,) arrays")
        bad = np.flatnonzero(~(self.lower < self.upper))
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"bounds of variable {i}: low={self.lower[i]} >= "
                             f"high={self.upper[i]}; expected low < high")
        if budget is not None and budget < 1:
            raise ValueError(f"budget={budget}: expected at least 1 evaluation or None")
        self.budget = None if budget is None else int(budget)
        self.names = tuple(names) if names is not None else None
        self.n_evals = 0
        self.best_value = np.inf
        self.best_point = None
        self.trace = Trace()

    @property
    def n_var(self):
        return self.lower.size

    @property
    def remaining(self):
        """Evaluations left (``None`` without a budget)."""
        return None if self.budget is None else self.budget - self.n_evals

    def _admit(self, X):
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if X.ndim != 2 or X.shape[1] != self.n_var:
            raise ValueError(f"X has shape {X.shape}; expected (pop, {self.n_var})")
        if self.budget is not None and self.n_evals >= self.budget:
            raise BudgetExhausted(f"budget of {self.budget} evaluations spent")
        n_take = X.shape[0] if self.budget is None else min(X.shape[0], self.remaining)
        return X, n_take

    def _record(self, X, values):
        """Count ``values`` (rows of ``X``) and update the best-so-far trace."""
        values = np.where(np.isfinite(values), values, np.inf)
        running = np.minimum.accumulate(values)
        # improvements: below the best so far and below every earlier row of the batch
        improved = running < self.best_value
        improved[1:] &= running[1:] < running[:-1]
        for i in np.flatnonzero(improved):
            self.best_value = float(values[i])
            self.best_point = X[i].copy()
            self.trace.evals.append(self.n_evals + int(i) + 1)
            self.trace.values.append(self.best_value)
            self.trace.points.append(self.best_point.tolist())
        self.n_evals += values.size
        return values

    def evaluate(self, X):
        """Objective values of the rows of ``X`` (pop, n_var) -> (pop,), counted."""
        X, n_take = self._admit(X)
        out = np.full(X.shape[0], np.inf)
        if n_take:
            out[:n_take] = self._record(X[:n_take], np.asarray(self.fun(X[:n_take]), float))
        return out

    def evaluate_residuals(self, X):
        """Residual vectors of the rows of ``X`` (pop, n_var) -> (pop, m), counted like
        :meth:`evaluate` (rows beyond the budget are ``inf``)."""
        if self.residual_fun is None:
            raise ValueError("this objective has no residual function")
        X, n_take = self._admit(X)
        res = np.asarray(self.residual_fun(X[:n_take]), dtype=float)
        out = np.full((X.shape[0], res.shape[1]), np.inf)
        out[:n_take] = res
        self._record(X[:n_take], np.einsum("ij,ij->i", res, res))
        return out

    def summary(self):
        """Plain-dict summary: evaluations, best value and point, trace."""
        return {
            "n_evals": self.n_evals,
            "best_value": self.best_value,
            "best_point": None if self.best_point is None else self.best_point.tolist(),
            "trace": {"evals": list(self.trace.evals), "values": list(self.trace.values)},
        }

