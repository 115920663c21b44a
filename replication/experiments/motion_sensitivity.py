"""Verdict sensitivity of the two "partly" motion rows (issue 12), as normal experiments.

- ``motion_flow_sensitivity``: the paper's claim that velocity fields are too noisy to find
  rotations (2.1), read through ``motion_accuracy``'s flow baselines: under which flow
  settings, moving-region choices and noise levels does an optical flow plus a rigid fit
  meet the accuracy goal? The claim holds under a reading when no flow method meets it on
  at least ``goal_rate`` of the sequences.
- ``segment_sensitivity``: section 2.3 done exactly as described (``segment_study``'s
  ``faithful`` method) under every choice the paper leaves open (population, generations,
  selection, sharing, size preference, disc radii, gradient threshold, snake iterations and
  tolerance): does it find ``goal_rate`` of the object-runs under any of them?

Both run their base experiment's runner per reading (:mod:`replication.experiments.sensitivity`).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from replication.experiments import motion as experiments
from replication.experiments import segment as segment_experiments
from replication.experiments.sensitivity import run_study
from replication.figures import sensitivity as figure
from replication.workers import kept_pools

FLOW_METHODS = ("TV-L1 flow + rigid fit", "iLK flow + rigid fit")
FAITHFUL = "faithful"


def flow_score(result):
    """Per flow method, the share of (sequence, noise) cases within the accuracy goal
    (the goal ``motion_accuracy``'s summary states per noise level), the medians over the
    cases with an estimate and ``n_failed``, the cases without one (no pixel left in the
    moving region: a miss); ``rate``: the best method's, ``points``: its cases (1 within
    the goal, 0 not)."""
    goals = {(s["method"], s["noise_255"]): (s["goal_px"], s["goal_pct"])
             for s in result["summary"]}
    per_method = {}
    for method in FLOW_METHODS:
        rows = [r for r in result["rows"] if r["method"] == method]
        if not rows:
            continue
        hits = [float(np.isfinite(r["centre_px"]) and np.isfinite(r["omega_pct"])
                      and r["centre_px"] <= goals[(method, r["noise_255"])][0]
                      and abs(r["omega_pct"]) <= goals[(method, r["noise_255"])][1])
                for r in rows]
        centre = np.array([r["centre_px"] for r in rows], dtype=float)
        omega = np.abs(np.array([r["omega_pct"] for r in rows], dtype=float))
        failed = ~(np.isfinite(centre) & np.isfinite(omega))   # no moving region left
        per_method[method] = {
            "rate": float(np.mean(hits)), "points": hits, "n_failed": int(failed.sum()),
            "centre_px_median": float(np.median(centre[~failed])) if (~failed).any() else None,
            "omega_pct_median": float(np.median(omega[~failed])) if (~failed).any() else None}
    best = max(per_method, key=lambda m: per_method[m]["rate"])
    return {"rate": per_method[best]["rate"], "points": per_method[best]["points"],
            "best_method": best, "methods": per_method}


def segment_score(result):
    """The ``faithful`` method on the study sequences: ``rate`` the share of object-runs
    found (``segment_study``'s criterion), ``points`` each run's share."""
    summary = next(s for s in result["summary"] if s["method"] == FAITHFUL)
    runs = [r for r in result["rows"] if r["method"] == FAITHFUL and r["role"] == "study"]
    return {"rate": summary["found_fraction"],
            "points": [float(np.mean([o["found"] for o in r["per_object"]])) for r in runs],
            "iou_median": summary["iou_median"],
            "false_regions_per_run": summary["false_regions_per_run"],
            "runs": summary["runs"]}


def flow_sensitivity(config, out):
    """Runner of ``motion_flow_sensitivity``. The readings share one flow cache
    (:func:`replication.motion.baselines.flow_field`): a flow field that depends neither on
    the reading's moving-region settings nor on the other method's options is computed
    once; the numbers are those of running each reading alone. The readings also share
    motion_accuracy's worker processes (a case depends only on its arguments)."""
    with tempfile.TemporaryDirectory(prefix="flow-cache-") as cache, kept_pools():
        def accuracy(reading, folder):
            flow = {**(reading.get("flow") or {}), "cache_dir": cache}
            return experiments.accuracy({**reading, "flow": flow}, folder)

        study = run_study(config, out, accuracy, flow_score)
    return _with_figure(study, config, ylabel="cases within the goal (best flow)",
                        title="Velocity fields (2.1): optical flow + rigid fit within the "
                              "accuracy goal, per reading")


def segment_sensitivity(config, out):
    """Runner of ``segment_sensitivity``."""
    study = run_study(config, out, segment_experiments.study, segment_score)
    return _with_figure(study, config, ylabel="object-runs found",
                        title="Section 2.3 exactly as described: object-runs found, "
                              "per reading")


def _with_figure(study, config, *, ylabel, title):
    if config.get("figure"):
        study["figure"] = figure.draw(Path(config["figure"]), study, ylabel=ylabel,
                                      title=title)
    return study
