"""Runners of the discrepancy experiments: one file, the worked example, the calibration and
the in-house blind study."""

from __future__ import annotations

import hashlib
import time
from pathlib import Path

import numpy as np

from replication.cloth.io import read_trajectory, write_trajectory
from replication.discrepancy import generate as gen
from replication.discrepancy.workflow import analyse
from replication.errors import InputError, check
from replication.progress import progress
from replication.provenance import file_sha256
from replication.results import write_json_atomic


def discrepancy(config, out):
    """``replicate experiment=discrepancy data.path=FILE out=DIR``: the whole workflow."""
    path = (config.get("data") or {}).get("path")
    if not path:
        raise InputError("data.path is not set: pass data.path=FILE (a trajectory .npz, "
                         "docs/data-formats.md)")
    trajectory = read_trajectory(path)
    settings = config.get("discrepancy") or {}
    progress(f"discrepancy workflow on {path}: {trajectory.n_frames} frames")
    result = analyse(trajectory, settings, rng=np.random.default_rng(config.get("seed")))
    names = [effect["name"] for effect in result["named_effects"]] or ["none"]
    progress(f"named: {', '.join(names)}; unexplained: {result['unexplained'] is not None}; "
             f"gap {result['gap_before']:.4g} -> {result['gap_after']:.4g} h")
    result["data_path"] = str(path)
    if config.get("plots", True):
        from replication.figures.discrepancy_where import plot_where
        target = Path(config.get("figures_dir") or out)
        result["plots"] = [str(p) for p in plot_where(result, target)]
    return result


def example(config, out):
    """A worked example: one dataset with a hidden effect, regenerated from its seed into
    ``out`` (not stored), analysed by :func:`discrepancy`; the spec goes to a manifest."""
    setting = config["example"]
    n_frames = int(setting["n_frames"])
    check(n_frames >= 100, f"example.n_frames={n_frames}: expected at least 100")
    rng = np.random.default_rng(config["seed"])
    spec = gen.draw_spec(rng, effects=[setting["effect"]],
                         noise_range=[setting["noise_h"], setting["noise_h"]])
    path = Path(out) / "example.npz"
    write_trajectory(path, gen.make_trajectory(spec, n_frames))
    run = dict(config)
    run["data"] = {"path": str(path)}
    start = time.perf_counter()
    result = discrepancy(run, out)
    result["analysis_seconds"] = time.perf_counter() - start
    result["hidden"] = spec
    result["hidden_coefficients"] = gen.truth_coefficients(spec, 0.001)
    manifest = Path(config["manifest"])
    # the output folders are left out: a run writes them to a staging folder first
    write_json_atomic(manifest, {"config": {k: v for k, v in config.items()
                                            if k not in ("out", "report", "figures_dir")},
                                 "spec": spec, "file": path.name,
                                 "sha256": file_sha256(path),
                                 "note": "regenerate with replicate experiment="
                                         f"{config['name']}"})
    return result


def calibration(config, out):
    """Effect-free datasets only: the null distribution of every decision statistic."""
    study = config["study"]
    n_datasets = int(study["n_datasets"])
    check(n_datasets >= 1, f"study.n_datasets={n_datasets}: expected at least 1")
    rng = np.random.default_rng(config["seed"])
    rows = []
    for index in range(n_datasets):
        spec = gen.draw_spec(rng, effects=["none"], noise_range=study["noise_range"])
        result = analyse(gen.make_trajectory(spec, int(study["n_frames"])),
                         config.get("discrepancy") or {},
                         rng=np.random.default_rng(spec["seed"]))
        ratios = {name: s["wald"] / s["threshold"] for name, s in result["candidates"].items()}
        rows.append({"noise_h": spec["noise_h"], "Q": result["where"]["Q"],
                     "max_wald_over_threshold": max(ratios.values()),
                     "significant": [n for n, s in result["candidates"].items()
                                     if s["significant"]],
                     "named": [e["name"] for e in result["named_effects"]],
                     "unexplained": result["unexplained"] is not None})
        progress(f"calibration {index + 1}/{n_datasets}: noise {spec['noise_h']:.2g} h, "
                 f"Q {rows[-1]['Q']:.2f}, max Wald/threshold "
                 f"{rows[-1]['max_wald_over_threshold']:.2f}")
    q = np.array([r["Q"] for r in rows])
    w = np.array([r["max_wald_over_threshold"] for r in rows])
    settings = config.get("discrepancy") or {}
    return {"datasets": rows, "summary": {
        "n_datasets": n_datasets,
        "Q_quantiles": {p: float(np.quantile(q, float(p))) for p in ("0.5", "0.9", "0.95")},
        "Q_max": float(q.max()),
        "q_threshold": settings.get("q_threshold"),
        "rate_Q_above_threshold": float(np.mean(q > settings.get("q_threshold", np.inf))),
        "wald_ratio_quantiles": {p: float(np.quantile(w, float(p)))
                                 for p in ("0.5", "0.9", "0.95")},
        "rate_any_significant": float(np.mean([bool(r["significant"]) for r in rows])),
        "false_name_rate": float(np.mean([bool(r["named"]) for r in rows])),
        "false_unexplained_rate": float(np.mean([r["unexplained"] for r in rows])),
    }}


def _coefficient_error(spec, named, mass):
    """Relative error of the fitted coefficients of a correct name, and each one's
    ``|fitted - truth| / standard error`` (``(None, None)`` when the name is wrong or the
    effect has no coefficients to compare; the ratios None without standard errors)."""
    truth = gen.truth_coefficients(spec, mass)
    if truth is None or not named or named[0]["name"] != spec["effect"]:
        return None, None
    parameters = named[0]["parameters"]
    fitted = np.array(list(parameters["coefficients"].values()))
    if fitted.shape != np.shape(truth):
        return None, None   # the library parametrises this effect differently (profiles)
    error = float(np.linalg.norm(fitted - truth) / np.linalg.norm(truth))
    se = parameters.get("standard_errors")
    if not se:
        return error, None
    se = np.array(list(se.values()))
    return error, (np.abs(fitted - truth) / np.maximum(se, np.finfo(float).tiny)).tolist()


def blind_study(config, out):
    """Hidden effects in generated data, analysed blind; rates, confusion, gaps, errors."""
    study = config["study"]
    n_datasets = int(study["n_datasets"])
    check(n_datasets >= 1, f"study.n_datasets={n_datasets}: expected at least 1")
    n_frames = int(study["n_frames"])
    check(n_frames >= 60, f"study.n_frames={n_frames}: expected at least 60")
    labels = list(study["effects"])
    rng = np.random.default_rng(config["seed"])
    rows = []
    for index in range(n_datasets):
        spec = gen.draw_spec(rng, effects=labels, noise_range=study["noise_range"])
        trajectory = gen.make_trajectory(spec, n_frames)
        digest = hashlib.sha256(np.ascontiguousarray(trajectory.positions).tobytes()).hexdigest()
        start = time.perf_counter()
        result = analyse(trajectory, config.get("discrepancy") or {},
                         rng=np.random.default_rng(spec["seed"]))
        wall = time.perf_counter() - start
        named = [effect["name"] for effect in result["named_effects"]]
        call = named[0] if named else ("unexplained" if result["unexplained"] else "none")
        expected = "unexplained" if spec["effect"] in gen.OUTSIDE_EFFECTS else spec["effect"]
        error, z = _coefficient_error(spec, result["named_effects"], 0.001)
        rows.append({
            "index": index, "spec": spec, "call": call, "correct": call == expected,
            "expected": expected,
            "gap_before": result["gap_before"], "gap_after": result["gap_after"],
            "Q": result["where"]["Q"], "noise_sigma_h_estimate": result["where"]["noise_sigma_h"],
            "coefficient_error": error, "coefficient_z": z,
            "wall_seconds": wall, "positions_sha256": digest,
        })
        progress(f"blind {index + 1}/{n_datasets}: hidden {spec['effect']} "
                 f"(noise {spec['noise_h']:.2g} h) -> {call} ({wall:.1f} s)")
    result = {"datasets": rows, "summary": summarise(rows, study)}
    manifest = {"config": {k: v for k, v in config.items() if k not in ("out", "report")},
                "note": "datasets are regenerated deterministically from these specs "
                        "(replication.discrepancy.generate.make_trajectory); sha256 of the "
                        "positions array bytes",
                "datasets": [{"spec": r["spec"], "positions_sha256": r["positions_sha256"]}
                             for r in rows]}
    write_json_atomic(Path(config["manifest"]), manifest)
    from replication.figures.discrepancy_blind import plot_blind
    result["figure"] = str(plot_blind(result, config["figure"]))
    return result


def summarise(rows, study):
    """Rates, confusion matrix, gap-shrink factors and coefficient errors of a blind study."""
    hidden = sorted({r["spec"]["effect"] for r in rows})
    calls = sorted({r["expected"] for r in rows} | {r["call"] for r in rows})
    confusion = {e: {c: 0 for c in calls} for e in hidden}
    for r in rows:
        confusion[r["spec"]["effect"]][r["call"]] += 1
    moderate = float(study["moderate_noise_h"])
    effect_rows = [r for r in rows if r["expected"] != "none"]
    moderate_rows = [r for r in effect_rows if r["spec"]["noise_h"] <= moderate]
    clean = [r for r in rows if r["expected"] == "none"]
    library = [r for r in effect_rows if r["expected"] != "unexplained"]
    shrink = [r["gap_before"] / r["gap_after"] for r in library
              if r["correct"] and r["gap_after"] > 0]
    errors = [r["coefficient_error"] for r in library if r["coefficient_error"] is not None]
    # do the stated standard errors cover the truth? (|error| / standard error: within 1 for
    # 68% and 2 for 95% of coefficients, median 0.674, were they exact and the errors normal)
    z = {r["index"]: r["coefficient_z"] for r in library if r.get("coefficient_z")}
    pooled = np.concatenate(list(z.values())) if z else np.zeros(0)
    beyond = [{"index": r["index"], "effect": r["spec"]["effect"],
               "noise_h": r["spec"]["noise_h"], "error": r["coefficient_error"],
               "z_max": max(z[r["index"]]) if r["index"] in z else None}
              for r in library if r["coefficient_error"] is not None
              and r["coefficient_error"] > 0.1]

    def rate(subset):
        return float(np.mean([r["correct"] for r in subset])) if subset else None

    return {
        "n_datasets": len(rows), "hidden": hidden, "calls": calls, "confusion": confusion,
        "correct_rate_all_effects": rate(effect_rows),
        "correct_rate_moderate_snr": rate(moderate_rows),
        "n_moderate": len(moderate_rows),
        "moderate_noise_h": moderate,
        "false_name_rate_effect_free": (float(np.mean([r["call"] != "none" for r in clean]))
                                        if clean else None),
        "n_effect_free": len(clean),
        "outside_effect_reported_unexplained": rate([r for r in rows
                                                     if r["expected"] == "unexplained"]),
        "gap_shrink_median": float(np.median(shrink)) if shrink else None,
        "gap_shrink": shrink,
        "coefficient_error_median": float(np.median(errors)) if errors else None,
        "coefficient_within_10pct": float(np.mean(np.array(errors) <= 0.1)) if errors else None,
        "coefficient_within_2se": (float(np.mean([max(v) <= 2.0 for v in z.values()]))
                                   if z else None),
        "coefficient_z_max": float(pooled.max()) if z else None,
        "coefficient_z_median": float(np.median(pooled)) if z else None,
        "coefficient_z_within": ({"1": float(np.mean(pooled <= 1.0)),
                                  "2": float(np.mean(pooled <= 2.0)), "n": int(pooled.size)}
                                 if z else None),
        "coefficient_beyond_10pct": beyond,
        "wall_seconds_median": float(np.median([r["wall_seconds"] for r in rows])),
        "wall_seconds_max": float(np.max([r["wall_seconds"] for r in rows])),
    }
