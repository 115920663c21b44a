"""Segmentation time against the number of objects (``bench_segment_objects``, issue 13,
beyond the paper).

For k = 1..8 objects, one sequence of fixed size (``side`` x ``side``) with the first k
cells of a 3 x 3 grid each holding a textured disc turning about a point near its middle
(:func:`replication.motion.multi_synth.make_multi_sequence`); the pipeline of
``bench_segment`` (``method``) runs on it ``repeats`` times after a warm-up, and is scored
as ``segment_study`` scores (IoU >= 0.7, centre within 2 px). Growth exponent: log-log
slope of the median time against k (:func:`replication.growth.exponent`).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from replication.errors import check
from replication.experiments.segment import score_objects
from replication.figures import growth as figure
from replication.growth import exponent
from replication.motion.multi_synth import MAX_OBJECTS, make_multi_sequence
from replication.motion.segment import pipeline as segmentation
from replication.progress import progress

# rotation speeds (rad/frame), object k takes the k-th; signs alternate
OMEGAS = (0.02, -0.03, 0.015, -0.025, 0.035, -0.018, 0.028, -0.022)
TEXTURE_SCALES = (1.5, 2.0, 2.5, 3.0, 1.8, 2.2, 2.8, 1.6)


def sequence_spec(k, side, radius):
    """The spec of the sequence with ``k`` objects (cells of a 3 x 3 grid, row by row)."""
    cell = side / 3.0
    objects = []
    for index in range(k):
        cx, cy = cell * (index % 3 + 0.5), cell * (index // 3 + 0.5)
        objects.append({"center": [round(cx + 4.0), round(cy - 3.0)], "omega": OMEGAS[index],
                        "texture": {"kind": "procedural", "scale": TEXTURE_SCALES[index]},
                        "shape": {"center": [cx, cy], "r_inner": 0, "r_outer": radius,
                                  "gap_deg": 0}})
    return {"shape": [side, side], "n_frames": 2, "supersample": 3, "noise_sigma": 0.0,
            "background_texture": {"kind": "procedural", "scale": 2.0}, "objects": objects}


def benchmark(config, out):
    """Runner of ``bench_segment_objects``.

    Parameters
    ----------
    config, out
        The resolved ``bench_segment_objects`` config (plain dict, docs/experiments.md) and
        the run's output folder.
    """
    counts = [int(k) for k in config["objects"]]
    check(len(counts) >= 2 and 1 <= min(counts) and max(counts) <= MAX_OBJECTS,
          f"objects={counts}: expected at least two counts from 1 to {MAX_OBJECTS}")
    repeats = int(config["repeats"])
    check(repeats >= 1, f"repeats={repeats}: expected at least 1")
    side, radius = int(config["side"]), float(config["radius"])
    check(2 * radius < side / 3.0, f"radius={radius}: expected below side / 6 = {side / 6:g}")
    settings = segmentation.settings_from(config.get("method"))
    rows = []
    for k in counts:
        frames, labels, truth = make_multi_sequence(sequence_spec(k, side, radius),
                                                    rng=[config["seed"], k])
        segmentation.segment(frames, settings, 0)   # warm-up
        times, found = [], []
        for run in range(repeats):
            start = time.perf_counter()
            objects = segmentation.segment(frames, settings, run + 1)["objects"]
            times.append(time.perf_counter() - start)
            scored = score_objects(objects, labels[0], truth)
            found.append(float(np.mean([o["found"] for o in scored["per_object"]])))
        rows.append({"objects": k, "seconds_median": float(np.median(times)),
                     "seconds": times, "found_fraction": float(np.mean(found))})
        progress(f"segmentation, {k} object(s): {rows[-1]['seconds_median']:.2f} s, "
                 f"{rows[-1]['found_fraction']:.0%} found")
    metrics = {"seconds_exponent_vs_objects": exponent(
        counts, [r["seconds_median"] for r in rows])}
    metrics.update({f"seconds_{r['objects']}_objects": r["seconds_median"] for r in rows})
    result = {"rows": rows, "metrics": metrics, "frame_side": side}
    if config.get("figure"):
        result["figure"] = figure.draw(Path(config["figure"]), [{
            "title": f"segmentation, {side} x {side} frames", "xlabel": "objects",
            "ylabel": "seconds (median)", "series": [{
                "label": "pipeline", "x": counts, "y": [r["seconds_median"] for r in rows],
                "exponent": metrics["seconds_exponent_vs_objects"]}]}],
            title="Segmentation: cost against the number of objects")
    return result
