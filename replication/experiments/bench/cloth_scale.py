"""Cost against mesh size and population (``bench_cloth_scale``, issue 13, beyond the paper).

- Step throughput: spring updates per second of the compiled step for a population of
  ``pop`` on an ``n x n`` sheet (n from 9 to 65), and against the population size on the
  17 x 17 sheet.
- Identification: the suite's identifier (:func:`replication.cloth.identify.identify`, the
  structured method, as ``cloth_identify`` runs it) on a noise-free reference trajectory of
  each mesh size, simulated here with the contract's model (K = 4, tau from the config):
  its time and its relative errors on K and tau.

Each curve's growth exponent is the log-log slope (:func:`replication.growth.exponent`).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from replication.cloth.identify import identify
from replication.cloth.io import trajectory_from_rollout
from replication.cloth.mesh import FAMILY_OF_TYPE
from replication.cloth.model import (
    initial_state,
    make_scene,
    params_from_vectors,
    reference_vector,
    simulate,
    step,
)
from replication.errors import check
from replication.experiments.bench.cloth import best_time
from replication.figures import growth as figure
from replication.growth import exponent
from replication.progress import progress


def step_rate(n, pop, *, tau, n_steps, repeats, rng, spread=0.2):
    """Spring updates per second of the compiled step: ``pop`` individuals (parameters
    within ``spread`` of the reference) on an ``n x n`` sheet, ``n_steps`` steps from the
    flat sheet, best of ``repeats`` after a warm-up."""
    scene = make_scene(n)
    truth = reference_vector(tau, n=n)
    params = params_from_vectors(truth * rng.uniform(1 - spread, 1 + spread, size=(pop, 5)))
    x0, v0 = initial_state(scene, pop)

    def run():
        x, v = x0, v0
        for _ in range(n_steps):
            x, v = step(x, v, params, scene)

    step(x0, v0, params, scene)   # compile / warm up
    seconds = best_time(run, repeats)
    return {"n": n, "pop": pop, "springs": scene.n_springs, "seconds": seconds,
            "spring_updates_per_second": pop * n_steps * scene.n_springs / seconds}


def identification(n, *, tau, frames, budget, seed):
    """The structured identifier (its default settings, ``budget`` cost evaluations) on a
    noise-free ``n x n`` reference of ``frames`` frames."""
    scene = make_scene(n)
    truth = reference_vector(tau, n=n)
    positions, _ = simulate(params_from_vectors(truth[None]), scene, frames - 1)
    trajectory = trajectory_from_rollout(positions[0], scene)
    start = time.perf_counter()
    best, _, _ = identify(trajectory, method="structured", rng=seed, budget=budget)
    seconds = time.perf_counter() - start
    # frames where some spring is held at its elongation limit: without any, tau is not
    # identifiable from the trajectory (any tau above the largest elongation fits it)
    x = positions[0]
    d = x[:, scene.spring_b] - x[:, scene.spring_a]
    rest = truth[:3][FAMILY_OF_TYPE[scene.spring_type]]
    ratio = np.linalg.norm(d, axis=2) / ((1.0 + truth[4]) * rest)
    return {"n": n, "frames": frames, "particles": n * n, "seconds": seconds,
            "constraint_active_fraction": float(np.mean(ratio.max(axis=1) > 1.0 - 1e-9)),
            "K_rel_error": float(best[3] / truth[3] - 1.0),
            "tau_rel_error": float(best[4] / truth[4] - 1.0)}


def benchmark(config, out):
    """Runner of ``bench_cloth_scale``.

    Parameters
    ----------
    config, out
        The resolved ``bench_cloth_scale`` config (plain dict, docs/experiments.md) and the
        run's output folder.
    """
    sizes = [int(n) for n in config["mesh_sizes"]]
    pops = [int(p) for p in config["populations"]]
    check(len(sizes) >= 2 and min(sizes) >= 3, f"mesh_sizes={sizes}: expected at least two "
          "sizes of at least 3")
    check(len(pops) >= 2 and min(pops) >= 1, f"populations={pops}: expected at least two "
          "positive sizes")
    tau, pop = float(config["tau"]), int(config["pop"])
    n_steps, repeats = int(config["n_steps"]), int(config["repeats"])
    rng = np.random.default_rng(config["seed"])
    by_mesh, by_pop, ident = [], [], []
    for n in sizes:
        by_mesh.append(step_rate(n, pop, tau=tau, n_steps=n_steps, repeats=repeats, rng=rng))
        progress(f"step, {n} x {n}, population {pop}: "
                 f"{by_mesh[-1]['spring_updates_per_second']:.3g} spring updates/s")
    for p in pops:
        by_pop.append(step_rate(int(config["population_mesh"]), p, tau=tau, n_steps=n_steps,
                                repeats=repeats, rng=rng))
        progress(f"step, population {p}: {by_pop[-1]['spring_updates_per_second']:.3g} "
                 "spring updates/s")
    for n in sizes:
        ident.append(identification(n, tau=tau, frames=int(config["frames"]),
                                    budget=int(config["budget"]), seed=config["seed"]))
        progress(f"identification, {n} x {n}: {ident[-1]['seconds']:.2f} s, K "
                 f"{100 * ident[-1]['K_rel_error']:+.3f} %, tau "
                 f"{100 * ident[-1]['tau_rel_error']:+.3f} %")
    springs = [r["springs"] for r in by_mesh]
    metrics = {
        "step_seconds_exponent_vs_springs": exponent(springs, [r["seconds"] for r in by_mesh]),
        "step_seconds_exponent_vs_population": exponent(pops, [r["seconds"] for r in by_pop]),
        "identify_seconds_exponent_vs_particles": exponent(
            [r["particles"] for r in ident], [r["seconds"] for r in ident]),
        "identify_max_abs_K_rel_error": max(abs(r["K_rel_error"]) for r in ident),
        # tau only where the constraint acts (else no trajectory tells it)
        "identify_max_abs_tau_rel_error_constraint_active": max(
            (abs(r["tau_rel_error"]) for r in ident if r["constraint_active_fraction"] > 0),
            default=None),
    }
    for r in by_mesh:
        metrics[f"spring_updates_per_second_n{r['n']}"] = r["spring_updates_per_second"]
    for r in by_pop:
        metrics[f"spring_updates_per_second_pop{r['pop']}"] = r["spring_updates_per_second"]
    for r in ident:
        metrics[f"identify_seconds_n{r['n']}"] = r["seconds"]
    result = {"by_mesh": by_mesh, "by_population": by_pop, "identification": ident,
              "metrics": metrics}
    if config.get("figure"):
        result["figure"] = figure.draw(Path(config["figure"]), [
            {"title": f"compiled step, population {pop}", "xlabel": "springs per sheet",
             "ylabel": "seconds", "series": [{
                 "label": f"{n_steps} steps", "x": springs, "y": [r["seconds"] for r in by_mesh],
                 "exponent": metrics["step_seconds_exponent_vs_springs"]}]},
            {"title": f"compiled step, {config['population_mesh']} x "
                      f"{config['population_mesh']} sheet", "xlabel": "population",
             "ylabel": "seconds", "series": [{
                 "label": f"{n_steps} steps", "x": pops, "y": [r["seconds"] for r in by_pop],
                 "exponent": metrics["step_seconds_exponent_vs_population"]}]},
            {"title": f"identification, {config['frames']} frames", "xlabel": "particles",
             "ylabel": "seconds", "series": [{
                 "label": "structured identifier", "x": [r["particles"] for r in ident],
                 "y": [r["seconds"] for r in ident],
                 "exponent": metrics["identify_seconds_exponent_vs_particles"]}]},
        ], title="Cloth: cost against mesh size and population")
    return result
