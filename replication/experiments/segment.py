"""Runners of the rigid-motion segmentation experiments (paper 2.3, Figs. 5-7).

Each runner takes the resolved config (plain dict) and the output folder, validates every
setting and input before writing anything, and returns the experiment's result keys.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path

import numpy as np

from replication.errors import check
from replication.motion.io import (
    check_shape,
    read_listed,
    read_manifest_sequences,
    read_sequence,
    write_sequence_folder,
    write_sequence_npz,
)
from replication.motion.multi_synth import MAX_OBJECTS, check_object, make_multi_sequence
from replication.progress import bar, progress
from replication.provenance import file_sha256
from replication.results import write_json_atomic


def _merged(base, override):
    spec = copy.deepcopy(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(spec.get(key), dict):
            spec[key] = {**spec[key], **value}
        else:
            spec[key] = copy.deepcopy(value)
    return spec


def make_data(config, out):
    """Write every configured multi-object sequence, its truth and labels, and a manifest.

    Sequence ``k`` (config order) draws textures and noise from ``default_rng([seed, k])``,
    so the bytes depend only on the config and the seed. The manifest holds the config and
    the sha256 of every file.

    Parameters
    ----------
    config, out
        The resolved ``motion_multi_data`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    items = list(config.get("sequences", {}).items())
    check(len(items) > 0, "sequences: empty; expected at least one sequence")
    specs = {name: _merged(config.get("base", {}), override) for name, override in items}
    for name, spec in specs.items():
        objects = spec.get("objects", [])
        check(1 <= len(objects) <= MAX_OBJECTS, f"sequences.{name}.objects: {len(objects)} "
              f"object(s); expected 1 to {MAX_OBJECTS}")
        for k, item in enumerate(objects):
            check_object(f"sequences.{name}.objects[{k}]", item)
        check(spec.get("format", "npz") in ("npz", "png8", "png16"),
              f"sequences.{name}.format: {spec.get('format')}; expected npz, png8 or png16")
        if "shape" in spec:
            check_shape(f"sequences.{name}.shape", spec["shape"])
    data_dir = Path(config["data_dir"])
    files, summary = {}, {}
    for index, (name, spec) in enumerate(specs.items()):
        progress(f"sequence {name}: {len(spec['objects'])} objects")
        frames, labels, truth = make_multi_sequence(
            spec, rng=np.random.default_rng([int(config["seed"]), index]))
        fmt = spec.get("format", "npz")
        if fmt == "npz":
            path = data_dir / f"{name}.npz"
            write_sequence_npz(path, frames, labels=labels, truth=truth)
            written = [path]
        else:
            path = data_dir / name
            written = write_sequence_folder(path, frames, labels=labels, truth=truth,
                                            bits=8 if fmt == "png8" else 16)
        files.update({str(p.relative_to(data_dir)): file_sha256(p) for p in written})
        summary[name] = {"path": str(path), "role": spec.get("role", "study"), "format": fmt,
                         "objects": truth["objects"],
                         "areas_px": [int(np.count_nonzero(labels[0] == o["label"]))
                                      for o in truth["objects"]],
                         "n_frames": int(frames.shape[0]),
                         "background_texture": spec.get("background_texture", {}).get("kind")}
    manifest = {"config": {k: v for k, v in config.items() if k != "out"},
                "sequences": summary, "files": files}
    write_json_atomic(data_dir / "manifest.json", manifest)
    progress(f"wrote {len(files)} files and manifest.json into data_dir")
    return {"data_dir": str(data_dir), "sequences": summary, "files": files}


def score_objects(objects, labels, truth, *, centre_px=2.0, iou_min=0.7):
    """Found objects against the truth of one sequence.

    Each true object (label ``k``, mask ``labels == k`` in frame 0) is matched to the found
    object of largest IoU with its mask; it is *found* when that IoU is at least ``iou_min``
    and the centre error at most ``centre_px``. A found object is *false* when most of its
    mask lies on the static background (label 0), and *split* when most of it lies on a
    true object that another found object matches better (the object found in pieces,
    or twice).

    Parameters
    ----------
    objects : list of dict
        ``xi, eta, omega, mask ((H, W) bool)``.
    labels : (H, W) ndarray of int
    truth : dict
        ``{"objects": [{label, xi, eta, omega}]}``.

    Returns
    -------
    dict
        ``per_object`` (label, iou, centre_px, omega_pct, found; the errors are None when
        no found object overlaps the true one), ``false_regions``, ``split_regions``,
        ``n_found_objects``.
    """
    rows, best_of = [], {}
    for item in truth["objects"]:
        true_mask = labels == item["label"]
        best_iou = 0.0
        for index, found in enumerate(objects):
            union = np.count_nonzero(true_mask | found["mask"])
            iou = np.count_nonzero(true_mask & found["mask"]) / union if union else 0.0
            if iou > best_iou:
                best_of[item["label"]], best_iou = index, iou
        row = {"label": item["label"], "iou": float(best_iou), "centre_px": None,
               "omega_pct": None, "found": False}
        if item["label"] in best_of:
            best = objects[best_of[item["label"]]]
            row["centre_px"] = float(np.hypot(best["xi"] - item["xi"], best["eta"] - item["eta"]))
            if item["omega"] != 0:
                row["omega_pct"] = float(100 * (best["omega"] - item["omega"])
                                         / abs(item["omega"]))
            row["found"] = bool(best_iou >= iou_min and row["centre_px"] <= centre_px)
        rows.append(row)
    false = split = 0
    for index, found in enumerate(objects):
        under = labels[np.asarray(found["mask"], dtype=bool)]
        if np.count_nonzero(under == 0) > 0.5 * under.size:
            false += 1
            continue
        values, counts = np.unique(under[under != 0], return_counts=True)
        if counts.size and 2 * counts.max() > under.size:   # most of it on one true object
            label = values[np.argmax(counts)]
            split += int(label in best_of and best_of[label] != index)
    return {"per_object": rows, "false_regions": int(false), "split_regions": int(split),
            "n_found_objects": len(objects)}


def _load(config):
    path = (config.get("data") or {}).get("path") or config.get("default_data")
    check(path is not None, "data.path: not set; expected a folder of frames or an .npz")
    return read_sequence(path), (config.get("data") or {}).get("path") is None


METHODS = ("pipeline", "faithful", "refined", "nichega", "flow")


def _study_sequences(config):
    manifest_path = Path(config["sequences_dir"]) / "manifest.json"
    sequences = read_manifest_sequences(manifest_path, "motion_multi_data")
    chosen = {name: item for name, item in sequences.items()
              if item["role"] in ("study", "static", "heldout")}
    limit = config.get("max_sequences")
    if limit is not None:
        study = [name for name, item in chosen.items() if item["role"] == "study"]
        chosen = {name: item for name, item in chosen.items()
                  if item["role"] == "static" or name in study[: int(limit)]}
    check(any(item["role"] == "study" for item in chosen.values()),
          f"{manifest_path}: no sequence with role 'study'; expected at least one")
    return chosen


def _with(settings, overrides):
    """``settings`` with some groups' values replaced, e.g. ``{"ea": {"keep": 0.1}}``."""
    return {**settings, **{group: {**(settings.get(group) or {}), **values}
                           for group, values in overrides.items()}}


def _run_method(method, frames, settings, flow_settings, rng, ablations=None):
    """Objects found by one method: ``pipeline`` (the configured settings), ``faithful``
    (the same with every addition to the paper switched off), ``refined`` (the pipeline
    then ``irc.refine`` of each object's rotation), ``nichega`` (pymoo's niching GA instead
    of the paper's EA), ``flow`` (TV-L1 + sequential RANSAC), or the name of an ablation
    (the pipeline with that ablation's overrides)."""
    from replication.motion.segment import baselines as segment_baselines
    from replication.motion.segment import pipeline as segmentation

    if method == "flow":
        return segment_baselines.flow_ransac_segment(frames, flow_settings, rng)
    chosen = {**settings, "search": "nichega" if method == "nichega" else "paper"}
    if method == "faithful":
        chosen = _with(chosen, segmentation.FAITHFUL)
    if ablations and method in ablations:
        chosen = _with(chosen, ablations[method])
    if method == "refined":
        chosen["accumulation"] = {**settings["accumulation"], "refine": True}
    return segmentation.segment(frames, chosen, rng)["objects"]


def _summarise_study(rows, methods, role="study"):
    summary = []
    for method in methods:
        mine = [r for r in rows if r["method"] == method and r["role"] == role]
        if not mine:
            continue
        objects = [o for r in mine for o in r["per_object"]]
        per_object = {}
        for r in mine:
            for o in r["per_object"]:
                per_object.setdefault(f"{r['sequence']}:{o['label']}", []).append(o["found"])
        rates = {key: float(np.mean(v)) for key, v in per_object.items()}
        detected = [o for o in objects if o["iou"] > 0]
        static = [r for r in rows if r["method"] == method and r["role"] == "static"]
        summary.append({
            "method": method, "runs": len(mine), "true_objects": len(objects),
            "found_fraction": float(np.mean([o["found"] for o in objects])),
            "objects_at_90pct": int(sum(rate >= 0.9 for rate in rates.values())),
            "objects": len(rates), "worst_object_rate": float(min(rates.values())),
            "per_object_rate": rates,
            "found_objects_per_run": float(np.mean([r["n_found_objects"] for r in mine])),
            "centre_px_median": float(np.median([o["centre_px"] for o in detected]))
            if detected else None,
            "omega_pct_median": float(np.median([abs(o["omega_pct"]) for o in detected]))
            if detected else None,
            "iou_median": float(np.median([o["iou"] for o in objects])),
            "false_regions_per_run": float(np.mean([r["false_regions"] for r in mine])),
            "split_regions_per_run": float(np.mean([r["split_regions"] for r in mine])),
            "static_false_regions_per_run": float(np.mean([r["false_regions"] for r in static]))
            if static else None,
            "seconds_median": float(np.median([r["seconds"] for r in mine])),
        })
    return summary


def study(config, out):
    """Every method on every study sequence for several seeds, scored against the truth.

    Run ``s`` of a method draws from ``default_rng([seed, sequence index, s])``; the static
    sequence (role ``static``) counts false regions only.

    Parameters
    ----------
    config, out
        The resolved ``segment_study`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    from replication.motion.segment import pipeline as segmentation
    from replication.motion.segment.baselines import FLOW_DEFAULTS

    settings = segmentation.settings_from(config.get("method"))
    flow_settings = {**FLOW_DEFAULTS, **(config.get("flow") or {})}
    seeds = {method: int(n) for method, n in (config.get("seeds") or {}).items()}
    ablations = dict(config.get("ablations") or {})
    for name, overrides in ablations.items():
        check(name not in METHODS, f"ablations.{name}: the name of a method; choose another")
        check(isinstance(overrides, dict) and all(isinstance(v, dict)
                                                  for v in overrides.values()),
              f"ablations.{name}: {overrides}; expected {{group: {{setting: value}}}}")
        segmentation.settings_from(_with(config.get("method") or {}, overrides))
    known = [*METHODS, *ablations]
    unknown = sorted(set(seeds) - set(known))
    check(not unknown, f"seeds: unknown method(s) {unknown}; expected some of {known}")
    check(all(n >= 0 for n in seeds.values()), f"seeds: {seeds}; expected counts >= 0")
    sequences = _study_sequences(config)
    loaded = read_listed(sequences, Path(config["sequences_dir"]) / "manifest.json")
    for sequence in loaded.values():
        check(sequence.truth is not None and sequence.labels is not None,
              f"{sequence.source}: truth or labels missing; expected both for the study")
    rows = []
    # a method with 0 seeds is not run (nor reported as finding nothing)
    plan = [(index, name, method, count) for index, name in enumerate(loaded)
            for method, count in seeds.items()
            if count > 0 and not (sequences[name]["role"] == "heldout" and method in ablations)]
    with bar(sum(count for *_, count in plan), "segmentation runs") as shown:
        for index, name, method, count in plan:
            sequence, role = loaded[name], sequences[name]["role"]
            for run in range(count):
                rng = np.random.default_rng([int(config["seed"]), index, run])
                start = time.perf_counter()
                objects = _run_method(method, sequence.frames, settings, flow_settings, rng,
                                      ablations)
                seconds = time.perf_counter() - start
                shown.update()
                score = score_objects(objects, sequence.labels[0], sequence.truth)
                rows.append({"sequence": name, "role": role, "method": method, "run": run,
                             "seconds": seconds, **score})
            mine = [r for r in rows if r["sequence"] == name and r["method"] == method]
            found = [o["found"] for r in mine for o in r["per_object"]]
            progress(f"{name} {method}: found {np.mean(found) if found else 0:.2f} of objects,"
                     f" {np.mean([r['false_regions'] for r in mine]) if mine else 0:.2f} false"
                     f" regions/run, {np.median([r['seconds'] for r in mine]) if mine else 0:.1f}"
                     " s/run")
    return {"sequences": {name: sequences[name] for name in loaded}, "seeds": seeds,
            "ablations": ablations,
            "rows": rows, "summary": _summarise_study(rows, list(seeds)),
            "summary_heldout": _summarise_study(rows, list(seeds), "heldout"),
            "goals": {"found_rate_at_least": 0.9, "centre_px_at_most": 2.0,
                      "iou_at_least": 0.7, "pipeline_seconds_at_most": 10.0}}


def benchmark(config, out):
    """Wall time of whole pipeline runs on one sequence (after a warm-up run), by step.

    Parameters
    ----------
    config, out
        The resolved ``bench_segment`` config (plain dict, docs/experiments.md) and the run's
        output folder.
    """
    from replication.motion.segment import pipeline as segmentation

    settings = segmentation.settings_from(config.get("method"))
    repeats = int(config.get("repeats", 3))
    check(repeats >= 1, f"repeats={repeats}: expected at least 1")
    sequence, _ = _load(config)
    segmentation.segment(sequence.frames, settings, 0)
    totals, steps, evaluations = [], [], 0
    for run in range(repeats):
        start = time.perf_counter()
        found = segmentation.segment(sequence.frames, settings, run + 1)
        totals.append(time.perf_counter() - start)
        steps.append(found["seconds"])
        evaluations = found["evaluations"]
    import numba

    search_s = float(np.median([s["search"] for s in steps]))
    metrics = {"pipeline_s_median": float(np.median(totals)), "pipeline_s_max": max(totals),
               "search_s_median": search_s,
               "snakes_s_median": float(np.median([s["snakes"] for s in steps])),
               "accumulation_s_median": float(np.median([s["accumulation"] for s in steps])),
               "assign_s_median": float(np.median([s["assign"] for s in steps])),
               "disc_evaluations_per_s": evaluations / search_s,
               "frame_pixels": int(np.prod(sequence.frames.shape[1:])),
               "numba_threads": numba.get_num_threads()}
    progress(f"pipeline {metrics['pipeline_s_median']:.2f} s (median of {repeats})")
    return {"data": sequence.source, "metrics": metrics, "goals": {"pipeline_s_at_most": 10.0}}
