"""``replicate experiment=bench``: every throughput figure of the suite in one result.json.

Gathers the ``metrics`` of the area benchmarks (``bench_*`` experiments, run before it by
``replicate-all``), the last full test-suite run (``results/tests.json``, written by the
test suite itself), the last full regeneration (``results/regenerate-full.json``,
written when ``replicate-all`` recomputed every result) and that of parts of the report
(``regenerate-part-PARTS.json``, ``replicate-all --force --part PARTS``), how much of the
baselines study's run time (``time_split``) is spent inside the cost, and the seconds of
the reference workload of :mod:`replication.machine` now.
"""

from __future__ import annotations

import json
from pathlib import Path

from replication.errors import check
from replication.machine import reference_seconds
from replication.results import read_result


def gather_benchmarks(config, out):
    """Collect area benchmark metrics, the test-suite time and the regeneration time.

    Parameters
    ----------
    config : dict
        The resolved ``bench`` config (``results_dir``: where ``bench_*/result.json``,
        ``tests.json`` and ``regenerate-full.json`` are read; ``goals``; ``time_split``:
        the experiment whose runs' time is split into cost and optimiser code, or null).
    out : Path
        The run's output folder.
    """
    results_dir = Path(config["results_dir"])
    check(results_dir.is_dir(), f"results_dir={results_dir}: no such folder")
    metrics, sources = {}, {}
    for path in sorted(results_dir.glob("bench_*/result.json")):
        result = read_result(path)
        name = result.get("experiment") or path.parent.name
        for key, value in result.get("metrics", {}).items():
            metrics[f"{name}.{key}"] = value
        sources[name] = {"wall_seconds": result.get("wall_seconds"),
                         "code_sha256": result.get("provenance", {}).get("code_sha256")}
    for label, filename, key in (("test_suite", "tests.json", "seconds"),
                                 ("last_full_regeneration", "regenerate-full.json",
                                  "total_seconds")):
        path = results_dir / filename
        if path.exists():
            record = json.loads(path.read_text())
            metrics[f"{label}_seconds"] = record.get(key)
            sources[label] = record
    # the last forced regeneration of some parts of the report alone (replicate-all
    # --force --part paper writes regenerate-part-paper.json)
    for path in sorted(results_dir.glob("regenerate-part-*.json")):
        label = f"last_regeneration_of_{path.stem.removeprefix('regenerate-part-')}"
        record = json.loads(path.read_text())
        metrics[f"{label}_seconds"] = record.get("total_seconds")
        sources[label] = record
    # the machine's speed now, beside those of the regeneration and test runs (timings of
    # different runs compare through it)
    metrics["machine_reference_seconds"] = reference_seconds()
    split = _time_split(results_dir, config.get("time_split"))
    if split is not None:
        sources["time_split"] = split
    return {"metrics": metrics, "sources": sources, "goals": config["goals"]}


def time_split(summary):
    """``{optimiser: (run_cpu_seconds, objective_cpu_seconds)}`` summed over the references
    of a study's ``summary``; ``None`` for a result made before the split was recorded in
    CPU time."""
    totals = {}
    for by_opt in summary.values():
        for name, s in by_opt.items():
            if "objective_cpu_seconds" not in s:
                return None
            run, inside = totals.get(name, (0.0, 0.0))
            totals[name] = (run + s["run_cpu_seconds"], inside + s["objective_cpu_seconds"])
    return totals


def _time_split(results_dir, name):
    """The runs' CPU time of experiment ``name`` (a baselines study) and the part of it
    spent inside the cost, summed over references, optimisers and seeds; None without
    them."""
    if name is None or not (results_dir / name / "result.json").exists():
        return None
    path = results_dir / name / "result.json"
    totals = time_split(read_result(path).get("summary", {}))
    if not totals:
        return None
    return {"experiment": name,
            "run_cpu_seconds": sum(run for run, _ in totals.values()),
            "objective_cpu_seconds": sum(inside for _, inside in totals.values())}
