"""scipy optimisers on an :class:`~replication.optim.objective.Objective`.

``least_squares`` needs residual vectors: the objective's ``residuals`` function, whose
squared norm is the objective value, counted exactly like ``evaluate``. Its finite-
difference Jacobian is computed here as one batch of ``n_var`` forward steps (counted as
``n_var`` evaluations), so that nothing is evaluated outside the objective.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from replication.optim.objective import BudgetExhausted


class _StartFailed(Exception):
    """A local run cannot go on: non-finite residuals where scipy needs finite ones (its
    start point, or a Jacobian step). Ends this start only; the next start follows."""


def _forward_jacobian(objective, x, f0, rel_step):
    """Forward-difference Jacobian ``(m, n_var)`` of the residuals at ``x``, one batch."""
    scale = np.maximum(np.abs(x), 1e-8 * (objective.upper - objective.lower))
    step = rel_step * scale
    # step inwards at the upper bound so that every point stays feasible
    step = np.where(x + step > objective.upper, -step, step)
    X = x[None, :] + np.diag(step)
    R = objective.evaluate_residuals(X)
    if not np.all(np.isfinite(R)):
        if objective.remaining == 0:  # the rows beyond the budget are inf
            raise BudgetExhausted("budget spent inside a Jacobian batch")
        raise _StartFailed("non-finite residuals in the Jacobian batch")
    return ((R - f0[None, :]) / step[:, None]).T


def run_least_squares(objective, *, rng, method="trf", rel_step=1e-6, max_starts=100_000,
                      options=None):
    """Multi-start ``scipy.optimize.least_squares`` until the objective's budget is spent.

    Each start is uniform in the objective's bounds, drawn from ``rng``; each local run
    ends on scipy's own tolerances or when the budget is spent.

    Parameters
    ----------
    objective : Objective
        With ``residuals`` and a budget.
    rng : np.random.Generator or int
    method : str
        ``least_squares`` method that honours bounds ("trf" or "dogbox").
    rel_step : float
        Relative forward-difference step of the Jacobian.
    options : dict, optional
        Further ``least_squares`` keywords (``xtol``, ``ftol``, ``gtol``, ``x_scale``).

    Returns
    -------
    dict with ``starts`` (number of local runs) and ``local_costs`` (final objective value
    of each completed local run).
    """
    if objective.budget is None:
        raise ValueError("run_least_squares needs an objective with a budget")
    rng = np.random.default_rng(rng)
    options = dict(options or {})
    starts, local_costs = 0, []
    cache = {}

    def residuals(x):
        # one row: evaluate_residuals raises BudgetExhausted once the budget is spent, so
        # a non-finite row is a real one (a blown-up simulation, a NaN)
        r = objective.evaluate_residuals(x[None, :])[0]
        if not np.all(np.isfinite(r)):
            if "x" not in cache:  # scipy refuses a non-finite start point
                raise _StartFailed("non-finite residuals at the start point")
            r = np.full_like(r, np.inf)  # scipy's trust region shrinks on a non-finite step
            return r
        cache["x"], cache["r"] = x.copy(), r
        return r

    def jacobian(x):
        if "x" not in cache or not np.array_equal(cache["x"], x):
            residuals(x)
            if not np.array_equal(cache["x"], x):  # non-finite at x: no Jacobian there
                raise _StartFailed("non-finite residuals where a Jacobian is needed")
        return _forward_jacobian(objective, x, cache["r"], rel_step)

    while objective.remaining > 0 and starts < max_starts:
        x0 = objective.lower + rng.random(objective.n_var) * (objective.upper - objective.lower)
        starts += 1
        cache.clear()
        try:
            fit = least_squares(residuals, x0, jac=jacobian,
                                bounds=(objective.lower, objective.upper), method=method,
                                **options)
            local_costs.append(float(2.0 * fit.cost))
        except _StartFailed:
            continue
        except BudgetExhausted:
            break
    return {"starts": starts, "local_costs": local_costs}
