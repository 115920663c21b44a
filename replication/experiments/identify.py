"""Runners of single identifications: any data file, the CI check, noise, speed.

``identify_run`` identifies one trajectory (``data.path`` or the config's reference) with
the chosen method and model; ``ci_check`` does the same and fails (exit 2, nothing
written) when a parameter leaves the tolerance of its config; ``noise_study`` adds
Gaussian position noise; ``bench`` times the paper's EA.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from replication.cloth.costs import structural_length
from replication.cloth.identify import EASettings, PaperEA, identify, problem
from replication.cloth.io import read_trajectory
from replication.errors import InputError, check
from replication.experiments.identify_common import check_common, data_files, run_rng
from replication.progress import bar, mode_for, progress

METHODS = ("structured", "paper_ea")


class ToleranceError(InputError):
    """An identified parameter is outside the tolerance of the CI check's config.

    A subclass of InputError so that ``replicate`` prints one line and exits with status 2
    without writing ``result.json``.
    """


def method_settings(config, method):
    """Settings of ``method`` from the config (validated).

    Parameters
    ----------
    config : dict
    method : "structured" or "paper_ea"
    """
    check(method in METHODS, f"method={method!r}: expected one of {', '.join(METHODS)}")
    if method == "paper_ea":
        EASettings.from_config(config["ea"])
        return {"ea": config["ea"], "rest_spread": config["init"]["rest_spread"]}
    return config["structured"]


def _single_trajectory(config):
    files = data_files(config)
    check(len(files) == 1, f"references: {len(files)} files; expected one (or data.path)")
    label, path = next(iter(files.items()))
    return label, path, read_trajectory(path)


def _identify(config, trajectory, rng):
    method, model = config["method"], str(config["model"])
    budget = config.get("budget")   # checked by identify(), before any work
    settings = method_settings(config, method)
    # validate bounds and cost frames before any work
    problem.search_space(trajectory, config["bounds"], model=model)
    problem.cost_from_config(trajectory, config["cost"])
    return identify(trajectory, model=model, rng=rng, budget=budget, method=method,
                    cost=config["cost"], bounds=config["bounds"], settings=settings)


# a parameter within this fraction of its search interval from a bound is "at the bound"
AT_BOUND = 1e-3


def bound_warnings(best, space, names):
    """One warning per identified parameter at (within :data:`AT_BOUND` of the interval
    of) a bound of the search space: the optimum may lie outside it, or the data may not
    determine the parameter.

    Parameters
    ----------
    best : (n_var,) array_like
    space : SearchSpace
    names : sequence of str
    """
    best = np.asarray(best, dtype=float)
    width = space.upper - space.lower
    warnings = []
    for i, name in enumerate(names):
        for side, bound in (("lower", space.lower[i]), ("upper", space.upper[i])):
            if abs(best[i] - bound) <= AT_BOUND * width[i]:
                warnings.append(f"best.{name}={best[i]:.6g} is at its {side} bound "
                                f"{bound:.6g}: the data may not determine it, or the answer "
                                "lies outside the bounds (bounds.*)")
    return warnings


def _identification_result(config, label, trajectory, best, cost, info):
    model = str(config["model"])
    names = problem.PARAM_NAMES_18 if model == "18" else problem.PARAM_NAMES_5
    population = [problem.named(x, names) for x in info["population"]]
    for row, value in zip(population, info.get("population_cost", [cost])):
        row["cost"] = float(value)
    truth = problem.truth_vector(trajectory, model)
    result = {"data": label, "method": config["method"], "model": model,
              "best": problem.named(best, names, cost), "population": population,
              "n_evals": info["n_evals"], "cost_used": config["cost"]}
    result["warnings"] = bound_warnings(best, problem.search_space(
        trajectory, config["bounds"], model=model), names)
    result["diagnostics"] = info["diagnostics"]
    result["warnings"] += info["warnings"]      # identify()'s, from the diagnostics
    budget = config.get("budget")
    if budget is not None and info["n_evals"] >= int(budget):   # structured or paper_ea
        result["warnings"].append(
            f"budget={budget}: every evaluation was spent, so {config['method']} stopped "
            "there, not at its own end; a larger budget may change the answer")
    if truth is not None:
        errors = problem.relative_errors(best, truth)
        result["relative_errors"] = dict(zip(names, errors.tolist()))
        result["truth"] = problem.named(truth, names)
        result["success"] = problem.is_success(best, truth, config["success_rtol"])
    return result


def identify_run(config, out):
    """Runner of ``cloth_identify`` (and ``cloth_identify_18``): one identification.

    Parameters
    ----------
    config, out
        The resolved ``cloth_identify`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    check_common(config)
    label, _, trajectory = _single_trajectory(config)
    best, cost, info = _identify(config, trajectory, run_rng(config["seed"]))
    progress(f"identified {label}: cost {cost:.3g} after {info['n_evals']} evaluations")
    return _identification_result(config, label, trajectory, best, cost, info)


def ci_check(config, out):
    """Runner of ``cloth_ci``: identify the good case; fail when a parameter leaves its
    tolerance (``tolerance: {name: relative}``) or, with ``check_misfit``, when the model
    at the true parameters does not explain the data (its one-step residuals more than
    ``problem.MISFIT_WARN`` times what the estimated position noise explains,
    :func:`problem.residual_fit`; written as ``truth_misfit``). The failure names
    every parameter outside its tolerance and the answer's warnings.

    Parameters
    ----------
    config, out
        The resolved ``cloth_ci`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    check_common(config)
    label, path, trajectory = _single_trajectory(config)
    model = str(config["model"])
    names = problem.PARAM_NAMES_18 if model == "18" else problem.PARAM_NAMES_5
    tolerance = config["tolerance"]
    check(set(tolerance) == set(names), f"tolerance: keys {sorted(tolerance)}; expected "
                                        f"one per parameter: {', '.join(names)}")
    check(all(float(v) > 0 for v in tolerance.values()),
          "tolerance: expected relative tolerances > 0")
    check_misfit = config.get("check_misfit", True)
    check(isinstance(check_misfit, bool), f"check_misfit={check_misfit!r}: expected true "
                                          "or false")
    truth = problem.truth_vector(trajectory, model)
    check(truth is not None, f"{path}: no meta.true_params; the CI check needs data with "
                             "known parameters")
    best, cost, info = _identify(config, trajectory, run_rng(config["seed"]))
    result = _identification_result(config, label, trajectory, best, cost, info)
    errors = result["relative_errors"]
    failures = [f"{name} = {best[i]:.6g} is {100 * errors[name]:+.3g}% from the truth "
                f"{truth[i]:.6g} (tolerance.{name}={tolerance[name]})"
                for i, name in enumerate(names) if abs(errors[name]) > float(tolerance[name])]
    if check_misfit:
        # at the true parameters, so that it judges the data against the model and not
        # the answer's accuracy (the tolerances do that; on noise-free data any answer
        # 1e-5 off already leaves residuals far above the noise floor)
        at_truth = problem.residual_fit(
            problem.cost_from_config(trajectory, config["cost"]), truth)["misfit"]
        result["truth_misfit"] = at_truth
        if not at_truth <= problem.MISFIT_WARN:
            failures.append(
                f"the model at the true parameters (meta.true_params) leaves one-step "
                f"residuals {at_truth:.3g} x what the position noise explains (check_misfit: "
                f"at most {problem.MISFIT_WARN:g}): the data disagree with the model or "
                "with their own truth (units, dt, frame order, an effect the model lacks)")
    if failures:
        warnings = "".join(f"\n  warning: {w}" for w in result["warnings"])
        raise ToleranceError(
            f"cloth_ci ({config['method']}, {info['n_evals']} evaluations on {label}): "
            + "; ".join(failures) + warnings)
    result["tolerance"] = tolerance
    result["check_misfit"] = check_misfit
    result["passed"] = True
    return result


def add_position_noise(trajectory, sigma, rng):
    """``trajectory`` with Gaussian noise of standard deviation ``sigma`` added to the
    positions of free particles; velocities are re-derived from the noisy positions.

    Parameters
    ----------
    trajectory : Trajectory
    sigma : float
        Standard deviation, in the trajectory's length unit.
    rng : np.random.Generator
    """
    scene = trajectory.scene()
    positions = trajectory.flat_positions().copy()
    noise = sigma * rng.standard_normal(positions.shape)
    positions[:, scene.free] += noise[:, scene.free]
    return dataclasses.replace(
        trajectory, positions=positions.reshape(trajectory.positions.shape), velocities=None)


def noise_study(config, out):
    """Runner of ``cloth_identify_noise``: parameter errors against position noise
    ``sigma = level * h`` for each method, ``n_seeds`` seeds (new noise and new search).

    Parameters
    ----------
    config, out
        The resolved ``cloth_identify_noise`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    check_common(config)
    label, path, clean = _single_trajectory(config)
    model = str(config["model"])
    truth = problem.truth_vector(clean, model)
    check(truth is not None, f"{path}: no meta.true_params; cloth_identify_noise needs data "
                             "with known parameters")
    levels = [float(v) for v in config["noise_levels"]]
    check(all(v >= 0 for v in levels), f"noise_levels={levels}: expected values >= 0")
    methods = list(config["methods"])
    for method in methods:
        method_settings(config, method)
    h = structural_length(clean)
    rows = []
    n_seeds = int(config["n_seeds"])
    combinations = [(li, level, mi, method) for li, level in enumerate(levels)
                    for mi, method in enumerate(methods)]
    for li, level, mi, method in bar(combinations, "noise levels x methods"):
        errors, successes, costs = [], [], []
        for i in bar(range(n_seeds), "seeds"):
            noisy = add_position_noise(clean, level * h, run_rng(config["seed"], li, i))
            run_config = {**config, "method": method}
            best, cost, _ = _identify(run_config, noisy, run_rng(config["seed"], li, mi, i))
            errors.append(problem.relative_errors(best, truth).tolist())
            successes.append(problem.is_success(best, truth, config["success_rtol"]))
            costs.append(cost)
        abs_err = np.abs(np.array(errors))
        rows.append({"noise_level": level, "sigma": level * h, "method": method,
                     "median_abs_errors": dict(zip(problem.PARAM_NAMES_5 if model == "5"
                                                   else problem.PARAM_NAMES_18,
                                                   np.median(abs_err, 0).tolist())),
                     "success_rate": float(np.mean(successes)),
                     "median_cost": float(np.median(costs)), "errors": errors})
        progress(f"noise {level} h, {method}: success {np.mean(successes):.2f}")
    return {"data": label, "h": h, "rows": rows, "model": model}


def bench(config, out):
    """Runner of ``bench_identify``: wall time of one paper-EA run (pop x generations)
    with the small and the full cost, best of ``repeats``.

    Parameters
    ----------
    config, out
        The resolved ``bench_identify`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    trajectory = read_trajectory(config["data_file"])
    settings = EASettings.from_config(config["ea"])
    repeats = int(config["repeats"])
    check(repeats >= 1, f"repeats={repeats}: expected >= 1")
    metrics, evals = {}, {}
    for kind in config["costs"]:
        cost = problem.cost_from_config(trajectory, {**config["cost"], "kind": kind})
        space = problem.search_space(trajectory, config["bounds"])
        cost(problem.params_from_vectors(space.lower[None, :]))  # compile / warm up
        times = []
        for r in range(repeats):
            rng = run_rng(config["seed"], r)
            objective = problem.cloth_objective(cost, space)
            initial = problem.random_population(space, settings.pop_size, rng,
                                                rest_spread=config["init"]["rest_spread"])
            with mode_for("none"):  # no live bar drawing beside the timed run
                start = time.perf_counter()
                PaperEA(objective, settings, rng, initial).run()
                times.append(time.perf_counter() - start)
        metrics[f"paper_ea_{kind}_cost_seconds"] = min(times)
        metrics[f"paper_ea_{kind}_cost_median_seconds"] = float(np.median(times))
        evals[kind] = objective.n_evals
        progress(f"paper EA, {kind} cost: best {min(times):.2f} s of {repeats}")
    return {"metrics": metrics, "evaluations_per_run": evals,
            "limits_seconds": dict(config["limits_seconds"])}

