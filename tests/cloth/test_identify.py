"""The paper's EA mechanics, the structured identifier and the cloth objective."""

import re

import numpy as np
import pytest

from replication.cloth.identify import (
    EASettings,
    PaperEA,
    identify,
    mutate,
    problem,
    reflect,
    uniform_crossover,
)
from replication.cloth.io import read_trajectory
from replication.errors import InputError
from replication.optim.objective import Objective

REFERENCE = "synthetic_data/cloth/reference_tau0.5.npz"
BOUNDS = {"rest": [0.8, 1.2], "K": [0.1, 10.0], "tau": [0.01, 1.0]}


@pytest.fixture(scope="module")
def trajectory():
    return read_trajectory(REFERENCE)


def quadratic_objective(n_var=5):
    return Objective(lambda X: ((np.asarray(X) - 0.3) ** 2).sum(axis=1), np.zeros(n_var),
                     np.ones(n_var))


def test_paper_rates_give_50_20_30_of_100():
    assert EASettings().counts() == (50, 20, 30)


@pytest.mark.parametrize("change, message", [
    ({"pop_size": 3}, "population under 4"),
    ({"keep": 0.6}, "rates do not add up"),
    ({"mutation_scale": 0.0}, "mutation_scale"),
    ({"mutate_from": 1.5}, "fraction in"),
])
def test_bad_ea_settings_are_refused_with_the_setting(change, message):
    with pytest.raises(InputError, match=message):
        EASettings.from_config(change)


def test_best_half_survives_unchanged_and_offspring_follow_the_rules():
    rng = np.random.default_rng(0)
    objective = quadratic_objective()
    settings = EASettings(pop_size=20, generations=0)
    ea = PaperEA(objective, settings, rng, rng.random((20, 5))).run()
    before_X, before_F = ea.X.copy(), ea.F.copy()
    children = ea.offspring()
    n_keep, n_mut, n_cross = settings.counts()
    assert children.shape == (n_mut + n_cross, 5)
    pool_mut = before_X[:16]   # best 80%
    for child in children[:n_mut]:
        changed = (np.abs(pool_mut - child) > 0).sum(axis=1)
        assert changed.min() == 1, "a mutant differs from a best-80% parent in one parameter"
    pool_cross = before_X[:10]   # best 50%
    for child in children[n_mut:]:
        for j, gene in enumerate(child):
            assert gene in pool_cross[:, j], "crossover genes come from best-50% parents"
    ea.step()
    kept = before_X[:n_keep]
    for row, value in zip(kept, before_F[:n_keep]):
        match = np.flatnonzero((ea.X == row).all(axis=1))
        assert match.size and ea.F[match[0]] == value
    assert np.all(np.diff(ea.F) >= 0) and objective.n_evals == 20 + n_mut + n_cross


def test_mutation_and_reflection_stay_in_bounds():
    rng = np.random.default_rng(1)
    lower, upper = np.zeros(3), np.ones(3)
    children = mutate(np.full((50, 3), 0.99), rng, lower=lower, upper=upper, scale=0.5,
                      n_params=2)
    assert np.all((children >= 0) & (children <= 1))
    assert np.allclose(reflect(np.array([1.2, -0.3, 2.5]), lower, upper), [0.8, 0.3, 0.5])
    pool = np.arange(12.0).reshape(4, 3)
    crossed = uniform_crossover(pool, 5, 3, rng)
    assert all(crossed[i, j] in pool[:, j] for i in range(5) for j in range(3))


def test_same_seed_same_paper_ea_run_on_the_cloth_cost(trajectory):
    runs = []
    for seed in (5, 5, 6):
        best, cost, info = identify(trajectory, rng=seed, method="paper_ea",
                                    settings={"ea": {"pop_size": 8, "generations": 3},
                                              "rest_spread": 0.1})
        runs.append((best.tolist(), cost, info["n_evals"]))
    assert runs[0] == runs[1] and runs[0] != runs[2]
    assert runs[0][2] == 8 + 3 * 4


def test_residuals_squared_sum_to_the_cost(trajectory):
    cost = problem.cost_from_config(trajectory, {"kind": "frames", "frames": [150, 300]})
    space = problem.search_space(trajectory, BOUNDS)
    X = problem.random_population(space, 4, np.random.default_rng(2), rest_spread=0.1)
    residuals = problem.residual_function(cost)(X)
    np.testing.assert_allclose((residuals ** 2).sum(axis=1),
                               cost(problem.params_from_vectors(X)), rtol=1e-9)


def test_structured_identifier_finds_the_truth_without_meta(trajectory):
    blind = type(trajectory)(**{**trajectory.__dict__, "meta": {}})
    settings = {"regression": {"first": 1, "stride": 5},
                "tau_scan": {"n_grid": 60, "refine_evals": 30},
                "refine": {"box": 0.02, "ea": {"pop_size": 8, "generations": 2}}}
    best, cost, info = identify(blind, rng=0, budget=1000, settings=settings)
    truth = problem.truth_vector(trajectory)
    assert problem.is_success(best, truth, 1e-6) and info["n_evals"] <= 1000
    assert info["warnings"] == []          # exact on clean data: nothing to warn about
    again, cost_again, info_again = identify(blind, rng=0, budget=1000, settings=settings)
    assert again.tolist() == best.tolist() and info_again["trace"] == info["trace"]


def test_bounds_low_not_below_high_are_refused(trajectory):
    with pytest.raises(InputError, match=r"bounds.K=\[5.0, 1.0\]: low >= high"):
        problem.search_space(trajectory, {**BOUNDS, "K": [5.0, 1.0]})


def test_frame_outside_the_data_is_refused(trajectory):
    with pytest.raises(InputError, match="outside the data"):
        problem.cost_from_config(trajectory, {"kind": "frames", "frames": [150, 900]})


@pytest.mark.parametrize("method, settings", [
    ("pymoo", {"algorithm": "de", "options": {"pop_size": 10}}),
    ("least_squares", {}),
])
def test_identify_runs_every_kind_of_the_solver_table_within_its_budget(trajectory, method,
                                                                       settings):
    """identify() and the baselines study share one solver table: the pymoo and scipy
    baselines run through identify() too, counted and reproducible from the seed."""
    runs = [identify(trajectory, rng=3, budget=60, method=method, settings=settings)
            for _ in range(2)]
    (best, cost, info), (again, cost_again, _) = runs
    assert info["n_evals"] == 60 and len(best) == 5
    assert best.tolist() == again.tolist() and cost == cost_again
    assert cost == min(info["trace"]["values"])


def test_identify_refuses_an_unknown_method_and_a_bad_algorithm(trajectory):
    with pytest.raises(InputError, match="method='simplex': expected one of paper_ea, "
                                         "structured, pymoo, least_squares"):
        identify(trajectory, method="simplex")
    with pytest.raises(InputError, match="algorithm='bfgs'"):
        identify(trajectory, method="pymoo", budget=10, settings={"algorithm": "bfgs"})
    for method in ("pymoo", "least_squares"):   # they run until the budget is spent
        with pytest.raises(InputError, match=f"method='{method}' runs until its budget"):
            identify(trajectory, method=method)


@pytest.mark.parametrize("change, message", [
    ({"trajectory": "reference.npz"}, "trajectory: a str; expected a Trajectory"),
    ({"budget": "abc"}, "budget='abc': expected an integer >= 1"),
    ({"budget": 2.5}, "budget=2.5: expected an integer >= 1"),
    ({"budget": 0}, "budget=0: expected an integer >= 1"),
    ({"model": 7}, "model=7: expected '5' or '18'"),
])
def test_identify_refuses_arguments_it_cannot_use(trajectory, change, message):
    arguments = {"trajectory": trajectory, **change}
    with pytest.raises(InputError, match=re.escape(message)):
        identify(arguments.pop("trajectory"), **arguments)


@pytest.mark.parametrize("change, message", [
    ({"positions": np.zeros_like}, "trajectory (made in memory): field 'positions': found "
                                   "particles (0, 0) and (0, 1) at the same place in frame 0"),
    ({"dt": -0.001}, "field 'dt': found -0.001; expected a time step > 0"),
    ({"pinned": [[0, 0], [0, 99]]}, "field 'pinned': found index (0, 99)"),
    ({"mass": "heavy"}, "field 'mass': found dtype <U5"),
    ({"meta": {"true_params": {"K": -1}}}, "field 'meta': found true_params.l01=null"),
])
def test_identify_checks_a_trajectory_made_in_memory_as_the_reader_does(trajectory, change,
                                                                        message):
    """A Trajectory built by hand is refused with the reader's line, naming the field (an
    all-zero one used to fail as 'bounds of variable 0: low=0.0 >= high=0.0')."""
    import dataclasses

    change = {key: value(getattr(trajectory, key)) if callable(value) else value
              for key, value in change.items()}
    made = dataclasses.replace(trajectory, source="<memory>", velocities=None, **change)
    with pytest.raises(InputError, match=re.escape(message)):
        identify(made, rng=0)


def test_identify_accepts_float32_and_lists_made_in_memory(trajectory):
    """What the reader accepts from a file, identify() accepts from memory: float32
    positions and pins as a list give the answer of the float64 data to float32 accuracy."""
    import dataclasses

    from replication.cloth.io import check_trajectory

    made = dataclasses.replace(trajectory, positions=trajectory.positions.astype(np.float32),
                               pinned=trajectory.pinned.tolist(), velocities=None,
                               source="<memory>")
    checked = check_trajectory(made)      # converted as the reader converts a file
    assert checked.positions.dtype == np.float64 and checked.pinned.dtype == np.int64
    assert checked.source == "<memory>" and checked.meta == made.meta
    best, _, info = identify(made, rng=0)
    reference, _, _ = identify(dataclasses.replace(trajectory, velocities=None), rng=0)
    assert np.allclose(best, reference, rtol=1e-3)


def test_identify_warns_when_the_model_does_not_explain_the_data(trajectory):
    """The reference played backwards, and a budget given as a numpy integer."""
    import dataclasses

    backwards = dataclasses.replace(trajectory, positions=trajectory.positions[::-1].copy(),
                                    velocities=None)
    best, cost, info = identify(backwards, rng=0, budget=np.int64(400), method="pymoo",
                                settings={"algorithm": "de", "options": {"pop_size": 20}})
    assert info["n_evals"] == 400
    assert any("leaves one-step residuals" in w for w in info["warnings"])


def test_read_trajectory_refuses_a_path_that_is_not_one():
    from replication.cloth.io import read_trajectory

    with pytest.raises(InputError, match="path: a NoneType; expected the path"):
        read_trajectory(None)


def test_structured_defaults_are_the_config_group():
    """identify()'s default structured settings are read from the config group, not kept
    as a copy in the code."""
    from omegaconf import OmegaConf

    from replication.cloth.identify import default_structured
    from replication.cli import CONFIG_DIR

    group = OmegaConf.to_container(OmegaConf.load(f"{CONFIG_DIR}/structured/default.yaml"))
    assert default_structured() == group and set(group) == {"regression", "tau_scan",
                                                            "refine"}


def test_no_finite_cost_at_all_is_a_refusal_not_a_crash():
    # a model whose arithmetic overflows at every vector: no best point to diagnose
    from replication.cloth.identify.problem import finite_best

    objective = Objective(lambda X: np.full(len(X), np.inf), np.zeros(2), np.ones(2))
    objective.evaluate(np.full((3, 2), 0.5))
    with pytest.raises(InputError, match="every one of the 3 parameter vectors tried gave a "
                                         "non-finite cost"):
        finite_best(objective)
    objective.evaluate(np.full((1, 2), 0.25))
    assert objective.best_point is None   # still none: inf is never a best
