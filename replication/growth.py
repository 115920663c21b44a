"""Cost-growth curves of the benchmarks: log-log slopes and one figure helper's data."""

from __future__ import annotations

import numpy as np


def exponent(sizes, values):
    """Least-squares slope of ``log(values)`` against ``log(sizes)``: ``values ~ sizes^slope``.

    None with fewer than two sizes or a value that is not positive and finite.

    Parameters
    ----------
    sizes, values : sequence of float
    """
    sizes = np.asarray(sizes, dtype=float)
    values = np.asarray(values, dtype=float)
    if sizes.size < 2 or not np.all(np.isfinite(values) & (values > 0)):
        return None
    slope, _ = np.polyfit(np.log(sizes), np.log(values), 1)
    return float(slope)
