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


def test_machine_reference_is_the_least_disturbed_timing(monkeypatch):
    from replication import machine

    # three timings of 5, 2 and 4 s, read from a clock the test controls
    clock = iter([0.0, 5.0, 10.0, 12.0, 20.0, 24.0])
    monkeypatch.setattr(machine, "_workload", lambda: None)
    monkeypatch.setattr(machine.time, "perf_counter", lambda: next(clock))
    assert machine.reference_seconds(repeats=3) == 2.0


def test_speed_summary_shows_the_machine_reference_of_each_run(tmp_path):
    _write(tmp_path / "regenerate-full.json",
           {"total_seconds": 500.0, "cpu_count": 2, "experiments": {"x": 500},
            "cpu_seconds": {"x": 900.0}, "machine_reference_seconds": 0.25})
    _write(tmp_path / "tests.json", {"seconds": 300.0, "machine_reference_seconds": 0.125})
    result = gather_benchmarks({"results_dir": str(tmp_path), "goals": {}}, tmp_path)
    now = result["metrics"]["machine_reference_seconds"]
    assert 0 < now < 60
    text = speed_section(result).markdown
    assert ("took 0.25 s at the start of the last full regeneration, 0.125 s at the end of "
            "the last full test run") in text
    # records made before the reference existed: only the gathering's own
    _write(tmp_path / "regenerate-full.json", {"total_seconds": 500.0})
    _write(tmp_path / "tests.json", {"seconds": 300.0})
    text = speed_section(gather_benchmarks({"results_dir": str(tmp_path), "goals": {}},
                                           tmp_path)).markdown
    assert "s when these figures were gathered" in text
    assert "at the start of the last full regeneration" not in text


def test_speed_summary_splits_the_regeneration_by_part(tmp_path):
    """CPU time per part of the report (each experiment's report.part), and the last forced
    regeneration of a part alone, from regenerate-part-PART.json."""
    _write(tmp_path / "regenerate-full.json",
           {"total_seconds": 500.0, "cpu_count": 2, "experiments": {},
            "cpu_seconds": {"fig08_mesh": 30.0, "table1_2": 10.0,
                            "cloth_baselines_budgets": 900.0, "not_a_config": 4.0}})
    _write(tmp_path / "regenerate-part-paper.json",
           {"total_seconds": 70.0, "cpu_count": 2, "cpu_seconds": {"fig08_mesh": 33.0,
                                                                   "table1_2": 11.0}})
    result = gather_benchmarks({"results_dir": str(tmp_path), "goals": {}}, tmp_path)
    assert result["metrics"]["last_regeneration_of_paper_seconds"] == 70.0
    text = speed_section(result).markdown
    assert "| `paper`: the paper's figures and tables | 2 | 40 | 20 |" in text
    assert "| `baselines`: the baselines on the paper's problems | 1 | 900 | 450 |" in text
    assert "| no `report.part` | 1 | 4 | 2 |" in text
    assert "`validation`" not in text   # no experiment of that part ran
    assert ("The last forced regeneration of the part(s) paper alone took 70 s on 2 CPUs, "
            "44 s of CPU.") in text
