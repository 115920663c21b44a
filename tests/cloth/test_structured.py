"""The structured identifier's stages, directly (replication.cloth.identify.structured)."""

import numpy as np
import pytest

from replication.cloth.identify import problem, structured
from replication.cloth.io import read_trajectory
from replication.cloth.mesh import FAMILY_OF_TYPE, N_TYPES
from replication.optim.objective import Objective

REFERENCE = "synthetic_data/cloth/reference_tau0.5.npz"
BOUNDS = {"rest": [0.8, 1.2], "K": [0.1, 10.0], "tau": [0.01, 1.0]}
SETTINGS = {"regression": {"first": 1, "stride": 5},
            "tau_scan": {"n_grid": 60, "refine_evals": 30},
            "refine": {"box": 0.02, "ea": {"pop_size": 8, "generations": 2}}}


@pytest.fixture(scope="module")
def case():
    trajectory = read_trajectory(REFERENCE)
    cost = problem.cost_from_config(trajectory, {"kind": "small"})
    space = problem.search_space(trajectory, BOUNDS)
    return trajectory, cost, space


def test_regression_frames_have_both_neighbours_in_the_data():
    frames = structured.regression_frames(20, first=0, stride=3)
    assert frames.tolist() == [1, 4, 7, 10, 13, 16]   # t - 1 >= 0 and t + 1 <= 19
    assert structured.regression_frames(3, first=5, stride=1).size == 0


def test_tau_groups_scan_all_then_each_family_then_each_type():
    assert structured.tau_groups("5", 5) == [[4]]
    groups = structured.tau_groups("18", 18)
    taus = list(range(12, 18))
    assert groups[0] == taus
    families = groups[1:4]
    assert sorted(i for family in families for i in family) == taus
    for family in families:   # one family per group: the clamp couples a family's taus
        assert len({FAMILY_OF_TYPE[i - 12] for i in family}) == 1
    assert groups[4:] == [[i] for i in taus] and len(groups) == 4 + N_TYPES


def test_tau_scan_finds_a_needle_that_a_grid_alone_misses():
    # cost = 1 - exp(-((log tau - log 0.3137) / 0.01)^2): a needle 1% wide in log tau, about
    # half a step of the 40-point log grid, so the refinement has to finish the job
    needle = 0.3137

    def fun(X):
        return 1.0 - np.exp(-((np.log(X[:, 1]) - np.log(needle)) / 0.01) ** 2)

    objective = Objective(fun, [0.0, 0.01], [1.0, 1.0])
    structured.scan_tau(objective, np.array([0.5, 0.05]), [1], n_grid=40, refine_evals=30)
    grid = np.geomspace(0.01, 1.0, 40)
    grid_best = grid[np.argmin(fun(np.c_[np.zeros(40), grid]))]
    assert abs(np.log(grid_best / needle)) > 0.005          # the grid alone is off the needle
    # 30 evaluations: 4 zooms of 7 values, each 3x narrower; the last spacing is about
    # 1/6 of (24% / 81), so the answer is within 3e-4 (relative) of the needle
    assert abs(objective.best_point[1] / needle - 1) < 3e-4
    assert objective.best_point[0] == 0.5                      # the other parameters stay
    assert objective.n_evals <= 40 + 30   # the grid and the zooms


def test_structured_identify_counts_every_evaluation_and_recovers_the_truth(case):
    trajectory, cost, space = case
    objective = problem.cloth_objective(cost, space, budget=1000)
    best, info = structured.structured_identify(trajectory, objective, space,
                                                rng=np.random.default_rng(0),
                                                settings=SETTINGS)
    truth = problem.truth_vector(trajectory)
    # the regression alone (no cost evaluation) is already close, the scan makes it exact
    assert problem.is_success(np.array(info["regression_vector"]), truth, 0.02)
    assert problem.is_success(best, truth, 1e-6)
    assert info["evals_after_scan"] <= objective.n_evals <= 1000
    # one evaluation of the regression's answer, then the scan's grid
    assert objective.trace.evals[0] == 1


def test_structured_identify_stops_cleanly_when_the_budget_runs_out(case):
    trajectory, cost, space = case
    objective = problem.cloth_objective(cost, space, budget=5)
    best, info = structured.structured_identify(trajectory, objective, space,
                                                rng=np.random.default_rng(0),
                                                settings=SETTINGS)
    assert objective.n_evals == 5 and "evals_after_scan" not in info
    assert best.tolist() == objective.best_point.tolist()


def test_the_refinement_box_shares_the_counter_and_narrows_the_bounds(case):
    _, cost, space = case
    objective = problem.cloth_objective(cost, space, budget=10)
    x = (objective.lower + objective.upper) / 2
    boxed = structured._BoxedObjective(objective, x * 0.98, x * 1.02)
    boxed.evaluate(x[None, :])
    assert objective.n_evals == boxed.n_evals == 1
    assert np.all(boxed.lower > objective.lower) and np.all(boxed.upper < objective.upper)


def test_engine_fit_is_computed_once_per_trajectory_and_forgotten_with_it(monkeypatch):
    import gc

    from replication.cloth import regression
    from replication.cloth.identify import structured
    from replication.cloth.io import read_trajectory

    calls = []
    real = regression.fit
    monkeypatch.setattr(regression, "fit", lambda *a, **k: calls.append(1) or real(*a, **k))
    trajectory = read_trajectory("synthetic_data/cloth/reference_tau0.5.npz")
    frames = structured.regression_frames(trajectory.n_frames, first=1, stride=25)
    first = structured.engine_fit(trajectory, frames, "5")
    assert structured.engine_fit(trajectory, frames, "5") is first and len(calls) == 1
    structured.engine_fit(trajectory, frames[::2], "5")            # other frames: a new fit
    assert len(calls) == 2
    key = id(trajectory)
    del trajectory
    gc.collect()
    assert key not in structured._FITS
