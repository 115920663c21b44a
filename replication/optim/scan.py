"""The one-dimensional search of the suite: a grid, then zooms around the best point.

Used wherever a single scalar is searched on a cost that is cheap to evaluate in batches
(one call of the compiled kernel per grid): the critical elongation rate tau of the
identification engine (:func:`replication.cloth.regression.search_tau`) and of the
structured identifier's tau scan (:func:`replication.cloth.identify.structured.scan_tau`).
A grid finds the basin of a needle-shaped minimum that a bracketing scalar method would
step over (Figs. 9-10); each zoom replaces the bracket around the current best grid point
``[g_{i-1}, g_{i+1}]`` by ``points`` equally spaced values, shrinking it by ``(points-1)/2``.
"""

from __future__ import annotations

import numpy as np


def zoom(evaluate, grid, *, levels, points=21, rtol=1e-10):
    """Minimise a scalar function over ``grid`` and then ``levels`` zooms.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(values) -> costs`` for a 1-D array of candidate values (one batch).
    grid : (m,) array_like
        The first grid, increasing.
    levels : int
        Zooms after the first grid (fewer when the bracket falls below ``rtol``).
    points : int
        Values per zoom (at least 4: with 3 the bracket would not shrink).
    rtol : float
        Stop when the bracket is narrower than ``rtol`` times its upper end.

    Returns
    -------
    best_value : float
        The point with the lowest cost seen (exact ties go to the one seen first, and
        within a grid to the smallest value).
    best_cost : float
    """
    if points < 4:
        raise ValueError(f"points={points}: a zoom needs at least 4 points")
    grid = np.asarray(grid, dtype=float)
    values = np.asarray(evaluate(grid), dtype=float)
    pick = int(np.argmin(values))
    best, best_cost = float(grid[pick]), float(values[pick])
    for _ in range(levels):
        lo, hi = grid[max(pick - 1, 0)], grid[min(pick + 1, len(grid) - 1)]
        if hi - lo <= rtol * hi:
            break
        grid = np.linspace(lo, hi, points)
        values = np.asarray(evaluate(grid), dtype=float)
        pick = int(np.argmin(values))
        if values[pick] < best_cost:
            best, best_cost = float(grid[pick]), float(values[pick])
    return best, best_cost
