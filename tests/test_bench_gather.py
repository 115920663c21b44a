"""The speed summary's bound: what the regeneration would cost if the baselines' optimiser
code took no time, from the baselines study's split of its run time."""

import json

from replication.experiments.bench.gather import gather_benchmarks
from replication.report.build import speed_section


def _write(path, value):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(value))


def test_bound_from_the_baselines_time_split(tmp_path):
    summary = {"ref": {"a": {"run_cpu_seconds": 30.0, "objective_cpu_seconds": 10.0},
                       "b": {"run_cpu_seconds": 10.0, "objective_cpu_seconds": 0.0}}}
    _write(tmp_path / "base/result.json", {"summary": summary})
    _write(tmp_path / "regenerate-full.json",
           {"total_seconds": 500.0, "cpu_count": 2, "experiments": {"base": 300, "x": 200},
            "cpu_seconds": {"base": 400.0, "x": 200.0}})
    result = gather_benchmarks({"results_dir": str(tmp_path), "goals": {},
                                "time_split": "base"}, tmp_path)
    assert result["sources"]["time_split"] == {"experiment": "base", "run_cpu_seconds": 40.0,
                                               "objective_cpu_seconds": 10.0}
    text = speed_section(result).markdown
    # a quarter of base's 400 s stays (100 s), plus x's 200 s: 300 s of CPU, 150 s on 2 CPUs
    assert "25% is spent inside the cost" in text
    assert "would still use 300 s of CPU: at least 150 s on 2 CPUs" in text


def test_no_bound_without_the_split(tmp_path):
    _write(tmp_path / "base/result.json", {"summary": {"ref": {"a": {"run_seconds": 3.0}}}})
    result = gather_benchmarks({"results_dir": str(tmp_path), "goals": {},
                                "time_split": "base"}, tmp_path)
    assert "time_split" not in result["sources"]
    assert "inside the cost" not in speed_section(result).markdown
