"""The discrepancy workflow tested blind on data made by an independent generator.

The datasets come from :mod:`replication.testdata.cloth_outside`, which imports nothing of
this package: its cloth model is written again from the contract and every effect from its
physical definition (area-weighted fluid force, masses as per-particle arrays, stiffness
per spring type, forces that vary in time or space and that no library term describes).
Each dataset is written to an ``.npz`` file and read back through the same reader as any
user's file; the workflow sees positions only.

An answer is exact when the named effects are exactly the library names of the effects
present (each once, nothing else) and "unexplained" is reported exactly when an effect
outside the library is present. Every rate is over the whole drawn set; the detection
limit (a signal-to-noise ratio of the weakest effect present, in the generator's
definition) is a config value, stated with the rates above and below it.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from replication.cloth.io import read_trajectory
from replication.discrepancy.workflow import LIMIT_CAVEAT, analyse
from replication.errors import InputError, check
from replication.experiments.outside_runs import run_datasets
from replication.progress import progress
from replication.results import write_json_atomic
from replication.sweep import cell_value
from replication.testdata import cloth_outside as og


def draw_specs(study, seed):
    """The study's dataset specs, drawn from one generator seeded by ``seed``: K and tau
    uniform over their ranges (the generator's draw), or, with ``study.log_uniform``,
    log-uniform (drawn after the generator's spec, from the same generator), which puts as
    many datasets in each decade of a wide range."""
    rng = np.random.default_rng(seed)
    kinds = list(study.get("kinds") or og.KINDS)
    specs = []
    for _ in range(int(study["n_datasets"])):
        spec = og.draw_spec(rng, kinds=kinds, frames_range=tuple(study["frames_range"]),
                            K_range=tuple(study["K_range"]),
                            tau_range=tuple(study["tau_range"]),
                            size_decades=tuple(study["size_decades"]))
        if study.get("log_uniform"):
            for key in ("K", "tau"):
                low, high = (float(v) for v in study[f"{key}_range"])
                spec[key] = float(np.exp(rng.uniform(np.log(low), np.log(high))))
        specs.append(spec)
    return specs


def _min_snr(truth):
    effects = truth["per_effect"]
    return float(min(e["snr"] for e in effects)) if effects else float("inf")


def run_one(spec, settings, folder):
    """Make one dataset, write and read it back, analyse it blind; one row."""
    made = og.make(spec)
    truth = made.pop("truth")
    path = Path(folder) / f"dataset_{spec['seed']}.npz"
    og.write_npz(path, made)
    start = time.perf_counter()
    try:
        result = analyse(read_trajectory(path), settings,
                         rng=np.random.default_rng(spec["seed"]))
    except InputError as error:   # a valid trajectory must never be refused: count it
        result = {"named_effects": [], "unexplained": None, "gap_before": float("nan"),
                  "gap_after": float("nan"), "refused": str(error),
                  "where": {"Q": float("nan"), "noise_sigma_h": float("nan")},
                  "base": {"fit": "refused"}, "final_base": {"k": [np.nan], "tau": [np.nan]}}
    wall = time.perf_counter() - start
    path.unlink()
    named = sorted(e["name"] for e in result["named_effects"])
    expected = sorted(truth["expected_names"])
    unexplained = result["unexplained"] is not None
    refused = result.get("refused")
    return {
        "spec": spec, "kinds": [e["kind"] for e in spec["effects"]],
        "expected_names": expected, "expected_unexplained": bool(truth["expected_unexplained"]),
        "named": named, "unexplained": unexplained, "refused": refused,
        "exact": (refused is None and named == expected
                  and unexplained == bool(truth["expected_unexplained"])),
        "min_snr": _min_snr(truth), "per_effect": truth["per_effect"],
        "noise_h": spec["noise_h"], "n_frames": spec["n_frames"],
        "gap_before": result["gap_before"], "gap_after": result["gap_after"],
        "Q": result["where"]["Q"], "noise_sigma_h_estimate": result["where"]["noise_sigma_h"],
        "base_fit": result["base"]["fit"], "K_fitted": result["final_base"]["k"][0],
        "tau_fitted": result["final_base"]["tau"][0],
        # a warning other than the detection-limit caveat, which every "none" at a high
        # limit carries, right or wrong; the caveat is counted apart
        "warned": any(not w.startswith(LIMIT_CAVEAT) for w in result.get("warnings", [])),
        "limit_caveat": any(w.startswith(LIMIT_CAVEAT) for w in result.get("warnings", [])),
        "warnings": list(result.get("warnings", [])),
        "wall_seconds": wall,
    }


def outside_study(config, out):
    """``replicate experiment=discrepancy_outside``: the blind study on outside data."""
    study = config["study"]
    n_datasets = int(study["n_datasets"])
    check(n_datasets >= 1, f"study.n_datasets={n_datasets}: expected at least 1")
    workers = int(study.get("workers") or 1)
    check(workers >= 1, f"study.workers={workers}: expected at least 1")
    specs = draw_specs(study, config["seed"])
    settings = config.get("discrepancy") or {}
    rows = run_datasets(run_one, specs, settings, workers=workers, report=_report)
    summary = summarise(rows, float(study["detection_snr"]))
    result = {"datasets": rows, "summary": summary}
    if config.get("manifest"):
        write_json_atomic(Path(config["manifest"]), {
            "generator": "replication.testdata.cloth_outside (imports nothing of the package)",
            "config": {k: v for k, v in config.items() if k not in ("out", "report")},
            "specs": specs})
    if config.get("figure"):
        from replication.figures.discrepancy_outside import plot_outside
        result["figure"] = str(plot_outside(result, config["figure"]))
    return result


def _report(index, total, row):
    called = ", ".join(row["named"]) or "none"
    hidden = ", ".join(row["kinds"]) or "none"
    progress(f"outside {index + 1}/{total}: hidden {hidden} (noise {row['noise_h']:.2g} h, "
             f"{row['n_frames']} frames) -> {called}"
             f"{' + unexplained' if row['unexplained'] else ''} "
             f"[{'exact' if row['exact'] else 'WRONG'}] ({row['wall_seconds']:.1f} s)")


def _rate(rows, key="exact"):
    return float(np.mean([bool(r[key]) for r in rows])) if rows else None


def summarise(rows, detection_snr):
    """Rates over the whole set, above and below the detection limit, by kind and noise."""
    clean = [r for r in rows if not r["kinds"]]
    with_effects = [r for r in rows if r["kinds"]]
    above = [r for r in with_effects if r["min_snr"] >= detection_snr]
    below = [r for r in with_effects if r["min_snr"] < detection_snr]
    named_right = [r for r in above if r["exact"] and r["expected_names"]]
    shrink = [r["gap_before"] / r["gap_after"] for r in named_right if r["gap_after"] > 0]
    by_kind = {}
    for kind in sorted({k for r in with_effects for k in r["kinds"]}):
        subset = [r for r in above if kind in r["kinds"]]
        by_kind[kind] = {"n_above": len(subset), "exact_above": _rate(subset),
                         "n_all": sum(kind in r["kinds"] for r in with_effects),
                         "exact_all": _rate([r for r in with_effects if kind in r["kinds"]])}
    noise_free = [r for r in clean if r["noise_h"] == 0]
    return {
        "n_datasets": len(rows), "n_effect_free": len(clean),
        "n_effect_free_noise_free": len(noise_free),
        "n_two_effects": sum(len(r["kinds"]) == 2 for r in rows),
        "n_outside": sum(r["expected_unexplained"] for r in rows),
        "detection_snr": detection_snr,
        "exact_rate_all": _rate(rows),
        "exact_rate_above_limit": _rate(above + clean), "n_above_limit": len(above) + len(clean),
        "exact_rate_effects_above_limit": _rate(above), "n_effects_above_limit": len(above),
        "exact_rate_below_limit": _rate(below), "n_below_limit": len(below),
        "false_names_effect_free": int(sum(bool(r["named"]) for r in clean)),
        "false_unexplained_effect_free": int(sum(r["unexplained"] for r in clean)),
        "false_names_effect_free_noise_free": int(sum(bool(r["named"]) for r in noise_free)),
        "gap_shrink_median": float(np.median(shrink)) if shrink else None,
        "n_gap_shrink": len(shrink),
        "by_kind": by_kind,
        "refused": int(sum(r["refused"] is not None for r in rows)),
        "n_wrong": int(sum(not r["exact"] for r in rows)),
        "wrong_warned": int(sum(not r["exact"] and r["warned"] for r in rows)),
        "exact_warned": int(sum(r["exact"] and r["warned"] for r in rows)),
        "wrong_caveat": int(sum(not r["exact"] and r["limit_caveat"] for r in rows)),
        "exact_caveat": int(sum(r["exact"] and r["limit_caveat"] for r in rows)),
        "wall_seconds_median": float(np.median([r["wall_seconds"] for r in rows])),
        "wall_seconds_max": float(np.max([r["wall_seconds"] for r in rows])),
    }


# the gathered documented sweep, committed beside the result folders (relative to the root)
SWEEP_CSV = Path("results/discrepancy_outside_sweep.csv")
_ROOT = Path(__file__).resolve().parents[2]
_ROW_FIELDS = ("exact", "min_snr", "noise_h", "n_frames", "unexplained", "expected_unexplained",
               "gap_before", "gap_after", "refused", "warned", "limit_caveat",
               "wall_seconds")
_ROW_LISTS = ("kinds", "named", "expected_names")


def rows_from_gathered(path=None):
    """Dataset rows of every run of a gathered sweep (``replicate-gather`` CSV), pooled.

    The CSV holds one line per run and one column per leaf of its ``result.json``
    (``datasets.N.exact``, ``datasets.N.kinds.0``, ...); this puts the datasets of all runs
    back into one list of rows that :func:`summarise` reads. Returns ``(rows, runs)``
    (``runs``: ``run``, ``seed``, ``code_sha256`` of each run, None when the CSV has no
    provenance), or ``([], [])`` when the file does not exist.
    """
    import csv

    path = _ROOT / SWEEP_CSV if path is None else Path(path)
    if not path.is_file():
        return [], []
    with open(path, newline="") as handle:
        lines = list(csv.DictReader(handle))

    rows, runs = [], []
    for line in lines:
        runs.append({"run": line.get("run"), "seed": cell_value(line.get("seed")),
                     "code_sha256": line.get("provenance.code_sha256") or None})
        index = 0
        while f"datasets.{index}.exact" in line and line[f"datasets.{index}.exact"] != "":
            head = f"datasets.{index}."
            row = {key: cell_value(line.get(head + key)) for key in _ROW_FIELDS}
            for key in _ROW_LISTS:
                items, k = [], 0
                while line.get(f"{head}{key}.{k}") not in (None, ""):
                    items.append(line[f"{head}{key}.{k}"])
                    k += 1
                row[key] = items
            row["exact"] = bool(row["exact"])
            row["unexplained"] = bool(row["unexplained"])
            row["warned"] = bool(row["warned"])
            row["limit_caveat"] = bool(row["limit_caveat"])
            row["min_snr"] = float(row["min_snr"])
            rows.append(row)
            index += 1
    return rows, runs
