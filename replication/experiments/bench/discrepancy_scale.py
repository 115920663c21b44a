"""Discrepancy workflow time against the number of frames (``bench_discrepancy_scale``,
issue 13, beyond the paper).

One dataset per length, made by the outside generator
(:mod:`replication.testdata.cloth_outside`) from one spec drawn with the config's seed
(the same sheet, noise and hidden effect at every length; only the number of frames
changes), written to ``.npz``, read back and analysed by
:func:`replication.discrepancy.workflow.analyse` as ``replicate experiment=discrepancy``
would; the time excludes making the data. Growth exponent: log-log slope of the time
against the frames (:func:`replication.growth.exponent`).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from replication.cloth.io import read_trajectory
from replication.discrepancy.workflow import analyse
from replication.errors import check
from replication.figures import growth as figure
from replication.growth import exponent
from replication.progress import progress
from replication.testdata import cloth_outside as og


def spec_for(config, n_frames):
    """The dataset spec at ``n_frames`` frames (every other draw the same at each length)."""
    data = config["dataset"]
    return og.draw_spec(np.random.default_rng(config["seed"]), kinds=[data["effect"]],
                        n_effects=1, noise_h=float(data["noise_h"]),
                        frames_range=(n_frames, n_frames),
                        size_decades=(float(data["size_decade"]),) * 2)


def benchmark(config, out):
    """Runner of ``bench_discrepancy_scale``.

    Parameters
    ----------
    config, out
        The resolved ``bench_discrepancy_scale`` config (plain dict, docs/experiments.md)
        and the run's output folder.
    """
    lengths = [int(n) for n in config["frames"]]
    check(len(lengths) >= 2 and min(lengths) >= 100,
          f"frames={lengths}: expected at least two lengths of at least 100 frames")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for n_frames in lengths:
            spec = spec_for(config, n_frames)
            made = og.make(spec)
            truth = made.pop("truth")
            path = Path(folder) / f"frames_{n_frames}.npz"
            og.write_npz(path, made)
            start = time.perf_counter()
            result = analyse(read_trajectory(path), config.get("discrepancy") or {},
                             rng=np.random.default_rng(spec["seed"]))
            seconds = time.perf_counter() - start
            named = sorted(e["name"] for e in result["named_effects"])
            rows.append({"frames": n_frames, "seconds": seconds, "named": named,
                         "expected": sorted(truth["expected_names"]),
                         "unexplained": result["unexplained"] is not None,
                         "gap_before": result["gap_before"], "gap_after": result["gap_after"]})
            progress(f"discrepancy, {n_frames} frames: {seconds:.1f} s -> "
                     f"{', '.join(named) or 'none'} (hidden {', '.join(rows[-1]['expected'])})")
    metrics = {"seconds_exponent_vs_frames": exponent(lengths, [r["seconds"] for r in rows])}
    metrics.update({f"seconds_{r['frames']}_frames": r["seconds"] for r in rows})
    result = {"spec": spec_for(config, lengths[0]), "rows": rows, "metrics": metrics}
    if config.get("figure"):
        result["figure"] = figure.draw(Path(config["figure"]), [{
            "title": "discrepancy workflow, one file", "xlabel": "frames",
            "ylabel": "seconds", "series": [{
                "label": "analyse", "x": lengths, "y": [r["seconds"] for r in rows],
                "exponent": metrics["seconds_exponent_vs_frames"]}]}],
            title="Discrepancy: cost against the number of frames")
    return result
