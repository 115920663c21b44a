"""The paper's costs on the reference runs (docs/cloth-model.md, "Costs")."""

import dataclasses

import numpy as np
import pytest

from replication.cloth import kernels
from replication.cloth.costs import make_cost
from replication.cloth.io import read_trajectory
from replication.cloth.model import ClothParams, params_from_vectors, reference_vector

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module", params=[0.1, 0.5])
def reference(request):
    path = ROOT / f"synthetic_data/cloth/reference_tau{request.param:g}.npz"
    return read_trajectory(path), reference_vector(request.param)


def test_costs_vanish_at_truth_and_grow_away_from_it(reference):
    trajectory, truth = reference
    for kind in ("small", "full"):
        cost = make_cost(trajectory, kind)
        X = np.array([truth, truth * [1.01, 1, 1, 1, 1], truth * [1, 1, 1, 0.9, 1],
                      truth * [1, 1, 1, 1, 0.8]])
        values = cost(params_from_vectors(X))
        assert values[0] < 1e-20
        assert np.all(values[1:] > 1e-14)


def test_full_cost_is_the_sum_of_its_50_frames(reference):
    trajectory, truth = reference
    full = make_cost(trajectory, "full", start=100, window=50)
    X = params_from_vectors(truth * [1.02, 0.99, 1.0, 1.1, 0.9])
    per_frame = sum(make_cost(trajectory, "small", frame=t)(X)[0] for t in range(100, 150))
    assert full.frames.tolist() == list(range(100, 150))
    assert full(X)[0] == pytest.approx(per_frame, rel=1e-12)


def test_velocity_term_weight_dtc(reference):
    trajectory, truth = reference
    X = params_from_vectors(truth * [1, 1, 1, 1.2, 1])
    positions_only = make_cost(trajectory, "small", dtc=0.0)(X)[0]
    default = make_cost(trajectory, "small")(X)[0]
    # with dtc = dt and v^ = (x^ - x_t)/dt, the velocity term equals the position term
    assert default == pytest.approx(2 * positions_only, rel=1e-9)


def test_blown_up_simulation_gives_infinite_cost_never_nan(reference):
    trajectory, truth = reference
    X = np.array([truth * [1, 1, 1, 1e307, 1], truth * [1, 1, 1, np.nan, 1], truth])
    for kind in ("small", "full"):
        values = make_cost(trajectory, kind)(params_from_vectors(X))
        assert not np.any(np.isnan(values))
        assert np.isinf(values[0]) and np.isinf(values[1]) and np.isfinite(values[2])


def test_tau_costs_equal_the_cost_of_the_repeated_population(reference):
    """The tau search's shortcut (forces once per frame, the constraint per tau) gives
    the very numbers of the general cost, with and without external forces (per frame or
    shared), from a constraint active on most springs to one that never acts."""
    trajectory, truth = reference
    cost = make_cost(trajectory, "full", start=100, window=12)
    base = params_from_vectors(truth * [1.03, 0.98, 1.0, 0.9, 1.0])
    rest, k = base.rest[0], base.k[0]
    tau = np.repeat(np.r_[np.geomspace(0.01, 2.0, 9), 1e307][:, None], 6, axis=1)
    rng = np.random.default_rng(3)
    P = trajectory.n ** 2
    for extra in (None, rng.normal(0, 1e-3, (1, 12, P, 3)), rng.normal(0, 1e-3, (1, 1, P, 3))):
        general = cost(params_from_vectors(np.c_[np.repeat(truth[None, :4] * [1.03, 0.98, 1.0,
                                                                               0.9], 10, 0),
                                                 tau[:, 0]]), extra)
        shortcut = cost.tau_costs(rest, k, tau, extra)
        assert np.array_equal(general, shortcut)
    with pytest.raises(ValueError, match="shared"):
        cost.tau_costs(rest, k, tau, np.zeros((2, 1, P, 3)))


def test_tau_costs_equal_the_general_cost_under_per_type_tau(reference):
    """The shortcut skips the springs no longer than their type's smallest limit in the
    batch and steps again only the particles that proposals move: with a tau per type
    (rows in any order, one NaN row that limits nothing) and noisy positions, where
    proposals land on some particles and not on others, the numbers are still the general
    cost's, bit for bit."""
    trajectory, truth = reference
    rng = np.random.default_rng(11)
    noisy = dataclasses.replace(trajectory, velocities=None, positions=trajectory.positions
                                + rng.normal(0.0, 2e-3, trajectory.positions.shape))
    cost = make_cost(noisy, "full", start=60, window=20)
    base = params_from_vectors(truth)
    rest, k = base.rest[0], base.k[0]
    tau = rng.uniform(0.0, 0.3, (40, 6))
    tau[7] = np.nan
    general = cost(ClothParams(np.repeat(rest[None], len(tau), 0),
                               np.repeat(k[None], len(tau), 0), tau))
    assert np.array_equal(general, cost.tau_costs(rest, k, tau))
    assert len(np.unique(general)) > 30   # the taus matter: proposals land on many rows


def test_tau_kernel_equals_the_general_kernel_bit_for_bit_on_small_random_scenes():
    """Small random meshes (pinned particles, springs between any two particles, masses and
    forces at random), taus of every sign and NaN or infinite, positions and velocities
    now and then NaN or infinite, and a spring exactly at its limit: the tau kernel's
    numbers have the bits of the general kernel's."""
    rng = np.random.default_rng(5)
    gravity, damping, dt = np.array([0.0, 0.0, -9.81]), 0.1, 0.01
    for _ in range(300):
        P, S, B, F, T = rng.integers(2, 7), rng.integers(1, 12), rng.integers(1, 6), 2, 4
        xs, vs = rng.normal(size=(T, P, 3)), rng.normal(size=(T, P, 3))
        if rng.random() < 0.2:
            xs[rng.integers(T), rng.integers(P), rng.integers(3)] = rng.choice(
                [np.nan, np.inf, -np.inf])
        if rng.random() < 0.1:
            vs[rng.integers(T), rng.integers(P), rng.integers(3)] = np.nan
        sa = rng.integers(0, P, S)
        sb = (sa + rng.integers(1, P, S)) % P
        st = rng.integers(0, 6, S)
        free, mass = rng.random(P) < 0.7, rng.uniform(0.5, 2.0, P)
        rest, k = rng.uniform(0.2, 2.0, 6), rng.uniform(0.0, 5.0, 6)
        tau = np.where(rng.random((B, 6)) < 0.5, rng.normal(0.0, 0.5, (B, 6)),
                       rng.choice([0.0, -0.0, 0.1, np.nan, np.inf, -np.inf], (B, 6)))
        frames = rng.integers(0, T - 1, F)
        extra = rng.normal(0.0, 0.1, (1, rng.choice([1, F]), P, 3))
        dtc = float(rng.choice([0.0, 0.01, 1.0]))
        scene = (sa, sb, st, free, mass, gravity, damping, dt)
        if rng.random() < 0.3:   # spring 0 exactly at its limit under tau = 0 (no forces)
            k[:] = 0.0
            force, x_pred = np.empty((P, 3)), np.empty((P, 3))
            kernels._predict_into(xs[frames[0]], vs[frames[0]], rest, k, extra[0, 0], sa, sb,
                                  st, free, mass, gravity, damping, dt, force, x_pred)
            d = x_pred[sb[0]] - x_pred[sa[0]]   # its length as the kernels compute it
            rest[st[0]] = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            tau[:, st[0]] = 0.0
        general = kernels.one_step_errors(xs, vs, frames, np.repeat(rest[None], B, 0),
                                          np.repeat(k[None], B, 0), tau, extra, dtc, *scene)
        shortcut = kernels.one_step_errors_tau(xs, vs, frames, rest, k, tau, extra, dtc, *scene)
        assert np.array_equal(general.view(np.int64), shortcut.view(np.int64))
