"""The paper's EA, the structured identifier and pymoo/scipy baselines on one objective.

Every optimiser minimises the same cost through the same counted
:class:`~replication.optim.objective.Objective` with the same bounds and budget, over
``n_seeds`` seeds per reference run. From each run's best-so-far trace: success (all
parameters within ``success_rtol``) at each fixed budget, evaluations to success, the
best cost and the parameter errors at each budget.
"""

from __future__ import annotations

import time

import numba
import numpy as np

from replication.cloth.identify import problem
from replication.cloth.identify.api import check_solver, solve
from replication.errors import InputError, check
from replication.experiments.identify_common import check_common, load_cases, outcome, run_rng
from replication.figures import cloth_baselines_ecdf
from replication.progress import bar, progress
from replication.workers import process_pool, usable_workers


def _check_optimisers(optimisers, paper_ea):
    check(len(optimisers) > 0, "optimisers: expected at least one entry")
    for entry in optimisers:
        try:
            check_solver(entry.get("kind"), _settings(entry, rest_spread=0.0,
                                                      paper_ea=paper_ea))
        except InputError as error:
            raise InputError(f"optimisers: {entry.get('name')}: {error}") from None


def _settings(entry, *, rest_spread, paper_ea):
    """The solver settings of one ``optimisers`` entry (see :func:`solve`); a ``paper_ea``
    entry's ``ea`` holds only what it changes of the paper's rates ``paper_ea``."""
    kind = entry.get("kind")
    if kind == "paper_ea":
        return {"ea": {**paper_ea, **(entry.get("ea") or {})}, "rest_spread": rest_spread}
    if kind == "structured":
        return entry["settings"]
    return {key: entry.get(key) for key in ("algorithm", "options")}


def run_optimiser(entry, case, *, budget, rng, seed, rest_spread, paper_ea):
    """One run of optimiser ``entry`` on ``case`` with ``budget`` evaluations.

    Returns the objective (its trace holds the run), the optimiser's own info and the CPU
    seconds spent inside the cost (the compiled kernel): what the optimiser's own code costs
    is the run's CPU time minus this.

    Parameters
    ----------
    entry : dict
        One item of the config's ``optimisers`` (``name``, ``kind`` and its settings).
    case : Case
    budget : int
        Evaluations allowed.
    rng : np.random.Generator
    seed : int
        pymoo's seed.
    rest_spread : float
        Initial spread of rest lengths (paper EA).
    paper_ea : dict
        The paper EA's rates (the config's ``ea``), under a ``paper_ea`` entry's own ``ea``.
    """
    kind = entry["kind"]
    objective = problem.cloth_objective(case.cost, case.space, budget=budget,
                                        with_residuals=kind == "least_squares")
    inside = [0.0]   # CPU seconds spent inside the cost

    def timed(fun):
        def call(X):
            start = time.process_time()
            try:
                return fun(X)
            finally:
                inside[0] += time.process_time() - start
        return call
    objective.fun = timed(objective.fun)
    if objective.residual_fun is not None:
        objective.residual_fun = timed(objective.residual_fun)
    info = solve(kind, objective, case.trajectory, case.space, rng=rng, seed=seed,
                 settings=_settings(entry, rest_spread=rest_spread, paper_ea=paper_ea))
    kept = {"paper_ea": (), "structured": ("regression",), "least_squares": ("starts",),
            "pymoo": tuple(info)}[kind]
    return objective, {key: info[key] for key in kept}, inside[0]


def _checkpoints(budget):
    """About 40 log-spaced evaluation counts from 1 to ``budget`` for convergence plots."""
    return np.unique(np.geomspace(1, budget, 40).round().astype(int)).tolist()


def score_run(objective, case, budgets, rtol):
    """Success, cost and errors at each budget, and evaluations to success, from a trace.

    Parameters
    ----------
    objective : Objective
        After the run: its trace.
    case : Case
    budgets : list of int
    rtol : float
        Success tolerance.
    """
    trace = objective.trace
    record = {"n_evals": objective.n_evals,
              "curve": [trace.best_at(b) for b in _checkpoints(max(budgets))],
              "at_budget": {}}
    for b in budgets:
        point = trace.point_at(b)
        entry = {"cost": trace.best_at(b)}
        if case.truth is not None and point is not None:
            errors = problem.relative_errors(point, case.truth)
            entry["errors"] = errors.tolist()
            entry["success"] = problem.is_success(point, case.truth, rtol)
            entry["outcome"] = outcome(point, case.truth, rtol)
        record["at_budget"][str(b)] = entry
    if case.truth is not None:
        record["evals_to_success"] = trace.first_eval_where(
            lambda x: problem.is_success(x, case.truth, rtol))
    return record


def _aggregate(records, budgets, names):
    """Per-optimiser summary over seeds."""
    out = {"n_runs": len(records)}
    hits = [r.get("evals_to_success") for r in records]
    reached = sorted(h for h in hits if h is not None)
    out["evals_to_success"] = hits
    out["median_run_seconds"] = float(np.median([r["run_seconds"] for r in records]))
    out["run_seconds"] = float(sum(r["run_seconds"] for r in records))
    out["run_cpu_seconds"] = float(sum(r["run_cpu_seconds"] for r in records))
    out["objective_cpu_seconds"] = float(sum(r["objective_cpu_seconds"] for r in records))
    out["median_evals_to_success"] = float(np.median(reached)) if reached else None
    for b in budgets:
        rows = [r["at_budget"][str(b)] for r in records]
        summary = {"median_cost": float(np.median([row["cost"] for row in rows]))}
        if "success" in rows[0]:
            summary["success_rate"] = float(np.mean([row["success"] for row in rows]))
            summary["valley_rate"] = float(np.mean(
                [row["outcome"] == "inactive-constraint valley" for row in rows]))
            errors = np.abs(np.array([row["errors"] for row in rows]))
            summary["median_abs_errors"] = dict(zip(names, np.median(errors, 0).tolist()))
        out[str(b)] = summary
    curves = np.array([r["curve"] for r in records], dtype=float)
    out["median_curve"] = np.median(curves, axis=0).tolist()
    return out


_CASES = {}


def _case_for(config, label):
    """The :class:`Case` of ``label``, loaded once per process."""
    key = (label, repr(config["cost"]), repr(config["bounds"]), repr(config.get("data")))
    if key not in _CASES:
        _CASES[key] = next(c for c in load_cases(config) if c.label == label)
    return _CASES[key]


def _one_run(task):
    """One (reference, optimiser, seed) run; top level so that worker processes can run it."""
    config, label, case_index, opt_index, i, budgets = task
    # most baselines evaluate one or a few vectors at a time: a parallel kernel region per
    # call costs more than it gains, so each worker runs its kernels on one thread
    numba.set_num_threads(min(int(config["threads_per_worker"]), numba.config.NUMBA_NUM_THREADS))
    case = _case_for(config, label)
    entry = config["optimisers"][opt_index]
    seed = int(run_rng(config["seed"], case_index, opt_index, i).integers(2**31))
    rng = run_rng(config["seed"], case_index, opt_index, i, 1)
    start, cpu_start = time.perf_counter(), time.process_time()
    objective, info, inside = run_optimiser(entry, case, budget=budgets[-1], rng=rng, seed=seed,
                                    rest_spread=config["init"]["rest_spread"],
                                    paper_ea=config["ea"])
    record = score_run(objective, case, budgets, float(config["success_rtol"]))
    record["info"] = info
    record["run_seconds"] = time.perf_counter() - start
    # CPU time, which other processes on the machine do not inflate: the run's, and the
    # part of it inside the cost
    record["run_cpu_seconds"] = time.process_time() - cpu_start
    record["objective_cpu_seconds"] = inside
    return record


def _map(tasks, workers):
    """Run tasks in order, in ``workers`` processes (1: in this process). Every run is
    seeded on its own, so the results do not depend on the number of workers."""
    label = "runs (reference x optimiser x seed)"
    if usable_workers(workers, label) == 1:
        threads = numba.get_num_threads()
        try:
            return [_one_run(task) for task in bar(tasks, label)]
        finally:
            numba.set_num_threads(threads)
    with process_pool(workers) as pool:
        return list(bar(pool.map(_one_run, tasks, chunksize=1), label, total=len(tasks)))


def baselines_study(config, out):
    """Runner of ``cloth_baselines``: every optimiser, ``n_seeds`` seeds, each reference.

    Parameters
    ----------
    config, out
        The resolved ``cloth_baselines`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    check_common(config)
    optimisers = config["optimisers"]
    _check_optimisers(optimisers, config["ea"])
    budgets = sorted(int(b) for b in config["budgets"])
    check(budgets[0] >= 1, f"budgets={budgets}: expected positive evaluation counts")
    workers = int(config.get("workers", 1))
    check(workers >= 1, f"workers={workers}: expected at least 1 process")
    cases = load_cases(config)
    names = list(cases[0].space.names)
    n_seeds = int(config["n_seeds"])
    tasks = [(config, case.label, ci, oi, i, budgets) for ci, case in enumerate(cases)
             for oi in range(len(optimisers)) for i in range(n_seeds)]
    progress(f"{len(tasks)} runs in {workers} process(es)")
    records = iter(_map(tasks, workers))
    summary, runs = {}, {}
    for case in cases:
        summary[case.label], runs[case.label] = {}, {}
        for entry in optimisers:
            chunk = [next(records) for _ in range(n_seeds)]
            runs[case.label][entry["name"]] = chunk
            summary[case.label][entry["name"]] = _aggregate(chunk, budgets, names)
    checkpoints = _checkpoints(budgets[-1])
    figures = cloth_baselines_ecdf.plot(summary, checkpoints, budgets[-1],
                                        ecdf_name=config["figures"]["ecdf"],
                                        convergence_name=config["figures"]["convergence"],
                                        figure_dir=config["figure_dir"])
    return {"budgets": budgets, "names": names, "checkpoints": checkpoints,
            "summary": summary, "runs": runs, "figures": figures,
            "cost_used": config["cost"]}
