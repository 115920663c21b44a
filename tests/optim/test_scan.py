"""The suite's one-dimensional search (replication/optim/scan.py), from its definition."""

import numpy as np
import pytest

from replication.optim.scan import zoom


def test_zoom_narrows_the_bracket_by_half_the_points_minus_one_each_level():
    calls = []

    def parabola(values):
        calls.append(np.array(values))
        return (np.asarray(values) - 0.123456789) ** 2

    best, cost = zoom(parabola, np.linspace(0.0, 1.0, 11), levels=6, points=7)
    assert len(calls) == 7 and [c.size for c in calls] == [11] + [7] * 6
    # bracket 0.2 after the grid, 3x narrower per zoom; the best is within half a spacing
    assert abs(best - 0.123456789) <= 0.2 / 3 ** 6 / 6 / 2 + 1e-15
    assert cost == pytest.approx((best - 0.123456789) ** 2, abs=0)
    for before, after in zip(calls[1:], calls[2:]):
        assert after[0] >= before[0] and after[-1] <= before[-1]   # nested brackets


def test_zoom_keeps_the_best_seen_and_breaks_ties_towards_small_values():
    flat = zoom(lambda v: np.zeros(len(v)), np.linspace(1.0, 2.0, 5), levels=3, points=5)
    assert flat == (1.0, 0.0)   # every value ties: the first (smallest) grid point stays

    def worse_inside(values):   # the grid's best is 0.5; every later value costs more
        values = np.asarray(values)
        return np.where(values == 0.5, 0.0, 1.0 + np.abs(values - 0.5))

    assert zoom(worse_inside, np.linspace(0.0, 1.0, 3), levels=4, points=4) == (0.5, 0.0)


def test_zoom_stops_when_the_bracket_is_below_rtol_and_refuses_three_points():
    calls = []

    def count(values):
        calls.append(len(values))
        return np.abs(np.asarray(values) - 1.0)

    zoom(count, np.array([1.0 - 1e-13, 1.0, 1.0 + 1e-13]), levels=5, points=5)
    assert calls == [3]   # the first bracket is already below 1e-10 of its upper end
    with pytest.raises(ValueError, match="points=3"):
        zoom(count, np.linspace(0, 1, 5), levels=1, points=3)
