"""``replicate experiment=bench_cloth``: throughput of the cloth step and of the costs.

The baseline is a plain per-individual numpy step (vectorised over springs, one
individual at a time), the straightforward way to write the model without a compiler.
"""

from __future__ import annotations

import time

import numba
import numpy as np

from replication.cloth.costs import make_cost
from replication.cloth.io import read_trajectory
from replication.cloth.model import initial_state, params_from_vectors, reference_vector, step
from replication.errors import check
from replication.progress import progress


def _scatter(index, values, size):
    """Sum rows of ``values`` (S, 3) into ``size`` rows by ``index`` (np.bincount per axis)."""
    return np.stack([np.bincount(index, weights=values[:, c], minlength=size)
                     for c in range(values.shape[1])], axis=1)


def numpy_step(x, v, rest, k, tau, scene):
    """One contract step for one individual in plain numpy. x, v : (P, 3); rest, k, tau : (6,).

    Parameters
    ----------
    x, v : (P, 3) ndarray
    rest, k, tau : (6,) ndarray
    scene : Scene
    """
    a, b, kind = scene.spring_a, scene.spring_b, scene.spring_type
    n_particles = len(x)
    mass = scene.mass[:, None]
    d = x[b] - x[a]
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    f = (k[kind] * (length - rest[kind]) / length)[:, None] * d
    force = (mass * scene.gravity - scene.damping * v + _scatter(a, f, n_particles)
             - _scatter(b, f, n_particles))
    free = scene.free[:, None]
    v1 = np.where(free, v + scene.dt * force / mass, 0.0)
    x1 = x + scene.dt * v1
    d = x1[b] - x1[a]
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    limit = (1.0 + tau[kind]) * rest[kind]
    over = length > limit
    free_a, free_b = scene.free[a], scene.free[b]
    share = np.where(free_a & free_b, 0.5, 1.0) * over
    move = ((length - limit) / length)[:, None] * d
    corr = (_scatter(a, (share * free_a)[:, None] * move, n_particles)
            - _scatter(b, (share * free_b)[:, None] * move, n_particles))
    count = (np.bincount(a, weights=over & free_a, minlength=n_particles)
             + np.bincount(b, weights=over & free_b, minlength=n_particles))
    x2 = x1 + corr / np.maximum(count, 1.0)[:, None]
    v2 = np.where(free, (x2 - x) / scene.dt, 0.0)
    return x2, v2


def best_time(function, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def _population(config, rng):
    truth = reference_vector(config["tau"])
    spread = float(config["spread"])
    return params_from_vectors(truth * rng.uniform(1 - spread, 1 + spread,
                                                   size=(config["pop"], 5)))


def bench_cloth(config, out):
    """Spring updates per second (compiled, and the numpy baseline) and cost timings.

    Parameters
    ----------
    config, out
        The resolved ``bench_cloth`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    pop, n_steps, repeats = int(config["pop"]), int(config["n_steps"]), int(config["repeats"])
    check(pop >= 1 and n_steps >= 1 and repeats >= 1,
          f"pop={pop}, n_steps={n_steps}, repeats={repeats}: expected positive integers")
    trajectory = read_trajectory(config["data"]["path"] or config["default_data"])
    rng = np.random.default_rng(config["seed"])
    params = _population(config, rng)
    scene = trajectory.scene()
    x0 = np.repeat(trajectory.flat_positions()[config["start_frame"]][None], pop, axis=0)
    v0 = np.repeat(trajectory.flat_velocities()[config["start_frame"]][None], pop, axis=0)

    def compiled():
        x, v = x0, v0
        for _ in range(n_steps):
            x, v = step(x, v, params, scene)
        return x

    compiled()  # compile / warm up
    progress(f"compiled step: {pop} individuals x {n_steps} steps, best of {repeats}")
    seconds = best_time(compiled, repeats)
    updates = pop * n_steps * scene.n_springs
    baseline_steps = int(config["baseline_steps"])

    def baseline():
        for i in range(pop):
            x, v = x0[i], v0[i]
            for _ in range(baseline_steps):
                x, v = numpy_step(x, v, params.rest[i], params.k[i], params.tau[i], scene)

    progress(f"numpy baseline: {pop} individuals x {baseline_steps} steps")
    baseline_seconds = best_time(baseline, 1)
    # the baseline is checked against the compiled step, or its speed means nothing
    x_np, _ = numpy_step(x0[0], v0[0], params.rest[0], params.k[0], params.tau[0], scene)
    x_nb, _ = step(x0[:1], v0[:1], params_from_vectors(
        np.concatenate([params.rest[0], params.k[0], params.tau[0]])), scene)
    h = float(np.linalg.norm(x0[0, 1] - x0[0, 0]))

    cost_times = {}
    for kind in ("small", "full"):
        cost = make_cost(trajectory, kind)
        cost(params)
        cost_times[kind] = best_time(lambda cost=cost: cost(params), repeats)
    init_x, _ = initial_state(scene)
    metrics = {
        "spring_updates_per_second_compiled_pop100": updates / seconds,
        "spring_updates_per_second_numpy_per_individual": pop * baseline_steps
        * scene.n_springs / baseline_seconds,
        "speedup_compiled_over_numpy": (updates / seconds)
        / (pop * baseline_steps * scene.n_springs / baseline_seconds),
        "small_cost_seconds_pop100": cost_times["small"],
        "full_cost_seconds_pop100": cost_times["full"],
        "numpy_vs_compiled_max_difference_h": float(np.abs(x_np - x_nb[0]).max() / h),
        "numba_threads": numba.get_num_threads(),
        "springs_per_individual": scene.n_springs,
        "particles_per_individual": int(init_x.shape[1]),
    }
    for name, value in metrics.items():
        progress(f"{name}: {value:.4g}")
    return {"metrics": metrics, "goal_spring_updates_per_second": config["goal"]}
