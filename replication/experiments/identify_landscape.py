"""Paper Figs. 9-10: the cost over (K, tau) with rest lengths fixed, and the EA's path.

Two windows per reference run: the paper's (K in [2, 4]; its tau interval [0.995, 1.01]
cannot contain 0.1 or 0.5, so it is read as a factor on the reference tau) and a wide one
(log axes) that shows the valleys; small and full cost. The paper EA's best individual per
generation (its own rest lengths, not fixed) is drawn on top.
"""

from __future__ import annotations

import numpy as np

from replication.cloth.identify.problem import cost_from_config
from replication.cloth.model import params_from_vectors
from replication.errors import check
from replication.experiments.identify_common import (
    check_common,
    load_cases,
    paper_ea_run,
    run_rng,
    score,
)
from replication.figures import fig09_10_landscapes
from replication.progress import bar, progress


def window_axes(window, tau_ref, n_grid):
    """Grid axes ``(K, tau)`` of a window: ``K: [lo, hi]`` and either ``tau_factor``
    (linear, times ``tau_ref``) or ``tau`` (absolute, log-spaced with log-spaced K).

    Parameters
    ----------
    window : dict
        ``K`` and ``tau_factor`` or ``tau`` (``[low, high]``).
    tau_ref : float
        The reference tau (``tau_factor`` multiplies it).
    n_grid : int
        Points per axis.
    """
    K_lo, K_hi = window["K"]
    check(K_lo < K_hi, f"window K={window['K']}: low >= high; expected low < high")
    if "tau_factor" in window:
        lo, hi = window["tau_factor"]
        check(lo < hi, f"window tau_factor={window['tau_factor']}: low >= high")
        return np.linspace(K_lo, K_hi, n_grid), tau_ref * np.linspace(lo, hi, n_grid), False
    lo, hi = window["tau"]
    check(0 < lo < hi, f"window tau={window['tau']}: expected 0 < low < high")
    return np.geomspace(K_lo, K_hi, n_grid), np.geomspace(lo, hi, n_grid), True


def cost_grid(cost, rest, Ks, taus):
    """Cost on the grid, shape (len(taus), len(Ks)), rest lengths (3,) fixed.

    Parameters
    ----------
    cost : ClothCost
    rest : (3,) ndarray
        Rest lengths of the three families.
    Ks, taus : 1-D ndarray
    """
    KK, TT = np.meshgrid(Ks, taus)
    X = np.column_stack([np.repeat(rest[None, :], KK.size, axis=0), KK.ravel(), TT.ravel()])
    return cost(params_from_vectors(X)).reshape(KK.shape)


def _grid_summary(grid, Ks, taus, tau_ref):
    i, j = np.unravel_index(np.argmin(grid), grid.shape)
    out = {"min_cost": float(grid[i, j]), "argmin_K": float(Ks[j]), "argmin_tau": float(taus[i])}
    above = taus > 1.2 * tau_ref
    if above.any():
        sub = grid[above]
        a, b = np.unravel_index(np.argmin(sub), sub.shape)
        out["valley"] = {"cost": float(sub[a, b]), "K": float(Ks[b]),
                         "tau": float(taus[above][a])}
    return out


def landscapes(config, out):
    """Runner of ``fig09_10``.

    Parameters
    ----------
    config, out
        The resolved ``fig09_10`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    settings = check_common(config)
    n_grid = int(config["grid"])
    check(n_grid >= 3, f"grid={n_grid}: expected at least 3 points per axis")
    cases = load_cases(config)
    kinds = list(config["costs"])
    costs = {case.label: {kind: cost_from_config(case.trajectory, {**config["cost"],
                                                                    "kind": kind})
                          for kind in kinds} for case in cases}
    results, figures = {}, []
    for case_index, case in enumerate(bar(cases, "reference runs")):
        reference = case.truth if case.truth is not None else np.r_[
            case.space.observed_rest[:3], np.nan, np.nan]
        tau_ref = reference[4] if case.truth is not None else float(config["tau_guess"])
        rest = reference[:3]
        panels = {}
        for kind in kinds:
            cost = costs[case.label][kind]
            at_truth = float(cost(params_from_vectors(reference))[0]) \
                if case.truth is not None else None
            for window_name, window in bar(config["windows"].items(), f"{kind} cost windows"):
                Ks, taus, log = window_axes(window, tau_ref, n_grid)
                grid = cost_grid(cost, rest, Ks, taus)
                panels[f"{kind}/{window_name}"] = {
                    "K": Ks, "tau": taus, "log": log, "cost": grid,
                    "summary": {**_grid_summary(grid, Ks, taus, tau_ref),
                                "cost_at_truth": at_truth}}
        ea, objective = paper_ea_run(case, settings, run_rng(config["seed"], case_index),
                                     rest_spread=config["init"]["rest_spread"])
        path = [[h["best_point"][3], h["best_point"][4], h["best"]] for h in ea.history]
        progress(f"landscapes of {case.label}: {len(panels)} panels, EA path "
                 f"{len(path)} generations")
        figures.append(fig09_10_landscapes.plot(
            panels, path, reference=(reference[3], tau_ref), title=case.label,
            out_name=config["figures"].get(case.label, f"landscape_{case.label}.png"),
            figure_dir=config["figure_dir"]))
        results[case.label] = {
            "panels": {name: p["summary"] for name, p in panels.items()},
            "ea_path": path, "ea_final": score(ea.X[0], case, config["success_rtol"]),
            "rest_fixed": rest.tolist(), "tau_reference": tau_ref,
        }
    return {"landscapes": results, "figures": figures}
