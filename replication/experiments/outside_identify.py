"""The cloth identifiers tested blind on data made by an independent generator, over the
whole range their bounds allow.

The datasets come from :mod:`replication.testdata.cloth_outside` (it imports nothing of this
package: its cloth model is written again from the contract), with no hidden effect: the
base model explains them exactly. The stiffness ``K`` and the critical elongation rate
``tau`` are drawn log-uniformly over ranges as wide as the identification bounds (soft and
weakly damped cloths included), the number of frames uniformly, and the position noise is
exactly 0 for a share of the datasets and log-uniform over several decades for the others.
Each dataset is written to an ``.npz`` file and read back through the reader of any user's
file; each identification is the one ``cloth_identify`` runs (with each method of
``methods``: its model, cost, bounds, budget and settings), with its warnings, and sees
positions only.

Every dataset is scored against the generator's truth: success when every parameter is
within ``success_rtol``; a failure without any warning is *silent*. The cost of the answer
is compared with the cost at the truth on the same objective: when the truth costs less,
the search missed a better point the data did determine (an optimiser failure, not data
that cannot tell the parameters apart). Rates are over the whole drawn set, and also per
regime of the constraint's activity (the share of free particle-steps the constraint moved,
from the generator's own run).
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from replication.cloth.identify import problem
from replication.cloth.model import params_from_vectors
from replication.cloth.io import read_trajectory
from replication.errors import InputError, check
from replication.experiments.identify import (_identification_result, _identify,
                                               method_settings)
from replication.experiments.identify_common import check_common, run_rng
from replication.experiments.outside_runs import run_datasets
from replication.progress import progress
from replication.testdata import cloth_outside as og

# the generator's rest lengths (its contract scene, no effect changes them): l01, l23, l45
TRUE_REST = (og.H, og.H * math.sqrt(2.0), 2.0 * og.H)


def _log_uniform(rng, interval):
    low, high = (float(v) for v in interval)
    return float(math.exp(rng.uniform(math.log(low), math.log(high))))


def check_study(study):
    """Refuse study settings the draw cannot use (InputError naming ``study.KEY``)."""
    n = study.get("n_datasets")
    check(isinstance(n, int) and not isinstance(n, bool) and n >= 1,
          f"study.n_datasets={n!r}: expected an integer >= 1")
    for key in ("K_range", "tau_range", "noise_h_range"):
        got = study.get(key)
        check(isinstance(got, (list, tuple)) and len(got) == 2
              and all(isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0
                      for v in got) and got[0] <= got[1],
              f"study.{key}={got!r}: expected [low, high] with 0 < low <= high")
    frames = study.get("frames_range")
    check(isinstance(frames, (list, tuple)) and len(frames) == 2
          and all(isinstance(v, int) and not isinstance(v, bool) for v in frames)
          and 3 <= frames[0] <= frames[1],
          f"study.frames_range={frames!r}: expected [low, high] integers with 3 <= low <= high")
    regimes = study.get("regimes")
    shares = [r.get("max_share") if isinstance(r, dict) else None for r in regimes or []]
    check(bool(shares) and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                               for v in shares)
          and shares == sorted(shares) and shares[-1] == 1,
          f"study.regimes: expected a list of {{label, max_share}} with max_share increasing "
          f"to 1; found max_share {shares}")
    zero = study.get("noise_zero_share")
    check(isinstance(zero, (int, float)) and not isinstance(zero, bool) and 0 <= zero <= 1,
          f"study.noise_zero_share={zero!r}: expected a share in [0, 1]")


def draw_specs(study, seed):
    """The study's dataset specs (the generator's, no effect), from one generator seeded by
    ``seed``: K and tau log-uniform, frames uniform, noise 0 with probability
    ``noise_zero_share`` else log-uniform over ``noise_h_range``."""
    rng = np.random.default_rng(seed)
    specs = []
    for _ in range(int(study["n_datasets"])):
        spec = og.draw_spec(rng, n_effects=0, noise_h=0.0,
                            frames_range=tuple(study["frames_range"]))
        spec["K"] = _log_uniform(rng, study["K_range"])
        spec["tau"] = _log_uniform(rng, study["tau_range"])
        spec["noise_h"] = (0.0 if rng.random() < float(study["noise_zero_share"])
                           else _log_uniform(rng, study["noise_h_range"]))
        specs.append(spec)
    return specs


def truth_of(spec):
    """The generator's parameters as the 5-parameter vector (l01, l23, l45, K, tau)."""
    return np.array([*TRUE_REST, spec["K"], spec["tau"]])


def run_one(spec, config, folder):
    """Make one dataset, write and read it back, identify it blind with each method of
    ``config["methods"]``; one row with ``answers: {method: {...}}``."""
    made = og.make(spec)
    truth = made.pop("truth")
    path = Path(folder) / f"dataset_{spec['seed']}.npz"
    og.write_npz(path, made)
    row = {"spec": spec, "K": spec["K"], "tau": spec["tau"], "noise_h": spec["noise_h"],
           "n_frames": spec["n_frames"],
           "constraint_share": truth["constraint_share"]}
    try:
        row["answers"] = {method: _answer(path, spec, {**config, "method": method})
                          for method in config["methods"]}
    finally:
        path.unlink()
    return row


def _answer(path, spec, config):
    """One method's identification of the dataset in ``path``, scored against ``spec``."""
    start = time.perf_counter()
    truth = truth_of(spec)
    try:
        trajectory = read_trajectory(path)
        best, cost, info = _identify(config, trajectory, run_rng(config["seed"], spec["seed"]))
        result = _identification_result(config, path.name, trajectory, best, cost, info)
    except InputError as error:   # a valid trajectory must never be refused: count it
        return {"refused": str(error), "success": False, "warned": False, "warnings": [],
                "relative_errors": None, "max_abs_error": None, "cost": None,
                "truth_cost": None, "truth_cheaper": None, "truth_in_bounds": None,
                "misfit": None, "noise_h_estimate": None, "n_evals": None,
                "wall_seconds": time.perf_counter() - start}
    space = problem.search_space(trajectory, config["bounds"], model="5")
    cost_fn = problem.cost_from_config(trajectory, config["cost"])
    truth_cost = float(cost_fn(params_from_vectors(truth[None, :]))[0])
    errors = problem.relative_errors(best, truth)
    return {"refused": None,
            "success": problem.is_success(best, truth, config["success_rtol"]),
            "warned": bool(result["warnings"]), "warnings": list(result["warnings"]),
            "relative_errors": dict(zip(problem.PARAM_NAMES_5, errors.tolist())),
            "max_abs_error": float(np.max(np.abs(errors))),
            "cost": float(cost), "truth_cost": truth_cost,
            "truth_cheaper": truth_cheaper(truth_cost, cost),
            "truth_in_bounds": bool(np.all((truth >= space.lower) & (truth <= space.upper))),
            "misfit": result["diagnostics"].get("misfit"),
            "noise_h_estimate": result["diagnostics"].get("noise_h"),
            "n_evals": int(info["n_evals"]), "wall_seconds": time.perf_counter() - start}


def answers_of(rows, method):
    """The dataset rows flattened for one method: dataset fields plus its answer."""
    return [{**{k: v for k, v in row.items() if k != "answers"}, **row["answers"][method]}
            for row in rows]


def truth_cheaper(truth_cost, cost, *, rtol=1e-3, floor=1e-20):
    """Whether the objective at the truth is lower than at the answer by more than round-off
    (``rtol`` of the answer's cost, and at least ``floor``, far above the round-off of a
    noise-free fit, about 1e-28 in the cost's units)."""
    return bool(cost - truth_cost > max(rtol * cost, floor))


def check_cost_frames(config, study):
    """Refuse a cost whose frames the shortest dataset does not hold, before any work: the
    cost is built on a dataset of ``frames_range[0]`` frames (any kind of cost)."""
    shortest = int(study["frames_range"][0])
    spec = {"n_frames": shortest, "K": 4.0, "tau": 0.5, "noise_h": 0.0, "seed": 0,
            "effects": []}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "shortest.npz"
        og.write_npz(path, og.make(spec))
        try:
            problem.cost_from_config(read_trajectory(path), config["cost"])
        except InputError as error:
            text = str(error).removeprefix(f"{path}: ")   # the file is only this check's
            raise InputError(f"study.frames_range={list(study['frames_range'])}: the "
                             f"shortest dataset ({shortest} frames) does not hold the cost: "
                             f"{text}") from None


def outside_identification(config, out):
    """``replicate experiment=cloth_identify_outside``: the blind study on outside data."""
    check_common(config)
    study = config["study"]
    check_study(study)
    check(str(config["model"]) == "5", f"model={config['model']!r}: the generator's cloth "
          "has one stiffness and one tau; expected model=5")
    check_cost_frames(config, study)
    workers = int(study.get("workers") or 1)
    check(workers >= 1, f"study.workers={workers}: expected at least 1")
    methods = config.get("methods")
    check(isinstance(methods, list) and methods and len(set(methods)) == len(methods),
          f"methods={methods!r}: expected a list of distinct methods")
    for method in methods:
        method_settings(config, method)
    specs = draw_specs(study, config["seed"])
    run_config = {k: v for k, v in config.items() if k not in ("report", "study")}
    rows = run_datasets(run_one, specs, run_config, workers=workers, report=_report)
    result = {"datasets": rows,
              "summary": {method: summarise(answers_of(rows, method), study["regimes"],
                                            config["success_rtol"])
                          for method in methods}}
    if config.get("figure"):
        from replication.figures.identify_outside import plot
        result["figure"] = plot({method: answers_of(rows, method) for method in methods},
                                config["success_rtol"], config["figure"],
                                config["figure_dir"])
    return result


def _report(index, total, row):
    said = []
    for method, answer in row["answers"].items():
        if answer["refused"]:
            verdict = "REFUSED"
        else:
            verdict = "ok" if answer["success"] else ("wrong, warned" if answer["warned"]
                                                      else "WRONG, SILENT")
        errors = answer["relative_errors"] or {}
        said.append(f"{method} K {100 * errors.get('K', math.nan):+.2g} %, tau "
                    f"{100 * errors.get('tau', math.nan):+.2g} % [{verdict}]")
    progress(f"outside {index + 1}/{total}: K {row['K']:.3g}, tau {row['tau']:.3g}, noise "
             f"{row['noise_h']:.2g} h, {row['n_frames']} frames -> " + "; ".join(said))


def _share(rows, key):
    return float(np.mean([bool(r[key]) for r in rows])) if rows else None


def _counts(rows):
    failed = [r for r in rows if not r["success"]]
    answered = [r for r in failed if r["refused"] is None]
    return {
        "n": len(rows),
        "success_rate": _share(rows, "success"),
        "n_failed": len(failed),
        "failed_warned": int(sum(r["warned"] for r in failed)),
        "failed_silent": int(sum(not r["warned"] and r["refused"] is None for r in failed)),
        "failed_truth_cheaper": int(sum(bool(r["truth_cheaper"]) for r in answered)),
        "failed_truth_outside_bounds": int(sum(r["truth_in_bounds"] is False
                                               for r in answered)),
        "succeeded_warned": int(sum(r["warned"] for r in rows if r["success"])),
        # how far off the answers that came without a warning are: the largest error a user
        # who trusts an unwarned answer can meet here
        "unwarned_max_abs_error": max((r["max_abs_error"] for r in rows
                                       if r["refused"] is None and not r["warned"]),
                                      default=None),
    }


# bands of the true position noise (units of h), at the identifier's own warning levels
NOISE_BANDS = ((0.0, problem.NOISE_WARN_H), (problem.NOISE_WARN_H, problem.NOISE_STRONG_H),
               (problem.NOISE_STRONG_H, math.inf))


def by_regime(rows, regimes):
    """Counts per regime of constraint activity (``regimes`` as in :func:`summarise`)."""
    groups = [(regime["label"], float(regime["max_share"]), []) for regime in regimes]
    for row in rows:
        for _, high, members in groups:
            if row["constraint_share"] <= high:
                members.append(row)
                break
    lows = [0.0] + [high for _, high, _ in groups[:-1]]
    return [{"label": label, "share_range": [low, high], **_counts(members)}
            for low, (label, high, members) in zip(lows, groups)]


def summarise(rows, regimes, rtol):
    """Rates over the whole set, for noise-free data, per band of position noise (the
    identifier's warning levels), and per regime of constraint activity (over all data and
    over the data under the first noise warning, so that noise and the constraint are told
    apart).

    Parameters
    ----------
    rows : list of dict
    regimes : list of dict
        ``{"label", "max_share"}`` in increasing ``max_share``: a dataset belongs to the
        first regime whose ``max_share`` its constraint share does not exceed.
    rtol : float
    """
    quiet = [r for r in rows if r["noise_h"] < NOISE_BANDS[0][1]]
    return {
        "success_rtol": rtol,
        "all": _counts(rows),
        "noise_free": _counts([r for r in rows if r["noise_h"] == 0.0]),
        "by_noise": [{"noise_h_range": [low, high if math.isfinite(high) else None],
                      **_counts([r for r in rows if low <= r["noise_h"] < high])}
                     for low, high in NOISE_BANDS],
        "by_regime": by_regime(rows, regimes),
        "by_regime_quiet": by_regime(quiet, regimes),
        "refused": int(sum(r["refused"] is not None for r in rows)),
        "wall_seconds_median": float(np.median([r["wall_seconds"] for r in rows])),
    }
