"""The compiled cloth step against the contract (docs/cloth-model.md)."""

import numpy as np
import pytest

from replication.cloth.mesh import springs
from replication.cloth.model import (
    ClothParams, Scene, initial_state, make_scene, params_from_vectors, reference_vector,
    simulate, step,
)
from tests.cloth.plain_reference import plain_run

H = 1.5 / 16


@pytest.mark.parametrize("tau", [0.1, 0.5])
def test_matches_plain_contract_loop_over_500_steps(tau):
    truth = reference_vector(tau)
    rest = [truth[0]] * 2 + [truth[1]] * 2 + [truth[2]] * 2
    plain = np.array(plain_run(500, rest, [4.0] * 6, [tau] * 6))
    positions, _ = simulate(params_from_vectors(truth), make_scene(), 500)
    error = np.abs(positions[0] - plain).max() / H
    assert error < 1e-9, f"max deviation {error:.3g} h"
    # the run must actually move and engage the constraint, or the check proves little
    assert np.abs(plain[-1] - plain[0]).max() > 5 * H


def test_spring_families_of_fig8():
    a, b, kind = springs(17)
    assert np.bincount(kind).tolist() == [272, 272, 256, 256, 255, 255]
    x = initial_state(make_scene())[0][0]
    lengths = np.linalg.norm(x[b] - x[a], axis=1)
    expected = np.array([H, H, H * np.sqrt(2), H * np.sqrt(2), 2 * H, 2 * H])
    np.testing.assert_allclose(lengths, expected[kind], rtol=1e-12)


def test_rest_mesh_without_gravity_stays_put():
    scene = make_scene(gravity=(0.0, 0.0, 0.0))
    x0, v0 = initial_state(scene)
    positions, velocities = simulate(params_from_vectors(reference_vector(0.1)), scene, 200,
                                     x0, v0)
    assert np.abs(positions[0, -1] - x0[0]).max() < 1e-12
    assert np.abs(velocities).max() < 1e-9


def test_internal_spring_forces_sum_to_zero():
    scene = make_scene(gravity=(0.0, 0.0, 0.0), pinned=np.zeros((0, 2), dtype=int))
    rng = np.random.default_rng(3)
    x0, v0 = initial_state(scene)
    x0 = x0 + rng.normal(scale=0.2 * H, size=x0.shape)
    params = params_from_vectors([[H, H * np.sqrt(2), 2 * H, 4.0, 10.0]])  # no constraint
    _, v1 = step(x0, v0, params, scene)
    momentum = scene.mass[:, None] * v1[0]
    assert np.abs(momentum.sum(axis=0)).max() < 1e-15
    assert np.abs(momentum).max() > 1e-7  # forces are there, they just cancel


def _lone_spring_scene(pinned_first):
    free = np.array([not pinned_first, True])
    return Scene(n=1, dt=0.002, mass=np.full(2, 0.001), gravity=np.zeros(3), damping=0.0,
                 pinned=np.zeros((0, 2), dtype=np.int64), spring_a=np.array([0]),
                 spring_b=np.array([1]), spring_type=np.array([0]), free=free)


@pytest.mark.parametrize("pinned_first", [False, True])
def test_lone_overstretched_spring_is_brought_back_to_limit(pinned_first):
    scene = _lone_spring_scene(pinned_first)
    rest, tau = 0.2, 0.1
    params = ClothParams(rest=np.full((1, 6), rest), k=np.zeros((1, 6)),
                         tau=np.full((1, 6), tau))
    x0 = np.array([[[0.0, 0.0, 0.0], [0.3, 0.4, 0.0]]])  # length 0.5 > 0.22
    x1, v1 = step(x0, np.zeros_like(x0), params, scene)
    length = np.linalg.norm(x1[0, 1] - x1[0, 0])
    assert abs(length - (1 + tau) * rest) < 1e-15
    direction = (x1[0, 1] - x1[0, 0]) / length
    np.testing.assert_allclose(direction, [0.6, 0.8, 0.0], atol=1e-15)
    if pinned_first:
        np.testing.assert_array_equal(x1[0, 0], x0[0, 0])
        np.testing.assert_array_equal(v1[0, 0], 0.0)
    else:  # half the excess to each end: the midpoint does not move
        np.testing.assert_allclose(x1[0].mean(axis=0), x0[0].mean(axis=0), atol=1e-15)


def test_compression_is_never_constrained():
    scene = _lone_spring_scene(False)
    params = ClothParams(rest=np.full((1, 6), 1.0), k=np.zeros((1, 6)),
                         tau=np.full((1, 6), 0.1))
    x0 = np.array([[[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]])
    x1, _ = step(x0, np.zeros_like(x0), params, scene)
    np.testing.assert_array_equal(x1, x0)


def test_velocities_equal_position_difference_and_pins_hold():
    scene = make_scene()
    positions, velocities = simulate(params_from_vectors(reference_vector(0.5)), scene, 100)
    np.testing.assert_allclose(velocities[0, 1:], np.diff(positions[0], axis=0) / scene.dt,
                               rtol=0, atol=1e-9)
    pinned = [0, 16]
    assert np.all(velocities[0, :, pinned] == 0.0)
    assert np.all(positions[0, :, pinned] == positions[0, :1, pinned])


def test_batched_equals_one_by_one_and_is_deterministic():
    rng = np.random.default_rng(0)
    X = reference_vector(0.3) * rng.uniform(0.8, 1.2, size=(6, 5))
    scene = make_scene()
    batched, _ = simulate(params_from_vectors(X), scene, 60)
    for i, row in enumerate(X):
        alone, _ = simulate(params_from_vectors(row), scene, 60)
        np.testing.assert_array_equal(batched[i], alone[0])
    again, _ = simulate(params_from_vectors(X), scene, 60)
    np.testing.assert_array_equal(batched, again)


def test_step_is_pure_and_18_parameter_form_matches_5():
    scene = make_scene()
    x0, v0 = initial_state(scene)
    x0_copy = x0.copy()
    five = reference_vector(0.1)
    eighteen = np.concatenate([five[[0, 0, 1, 1, 2, 2]], np.full(6, 4.0), np.full(6, 0.1)])
    x5, v5 = step(x0, v0, params_from_vectors(five), scene)
    x18, v18 = step(x0, v0, params_from_vectors(eighteen), scene)
    np.testing.assert_array_equal(x0, x0_copy)
    np.testing.assert_array_equal(x5, x18)
    np.testing.assert_array_equal(v5, v18)


def test_params_refuse_wrong_width():
    with pytest.raises(ValueError, match="expected 5 or 18"):
        params_from_vectors(np.zeros((2, 7)))
