"""replicate-all: per-experiment code hashes, cache keys and the parallel scheduler."""

import sys
import time

import pytest

from replication import provenance
from replication.regenerate import experiment_keys, resolved_configs, run_scheduled
from replication.report.build import experiment_entries


def _relative(files):
    return {str(path.relative_to(provenance.PROJECT_ROOT)) for path in files}


def test_code_of_a_cloth_runner_excludes_the_motion_code():
    files = _relative(provenance.module_closure(["replication.experiments.bench.cloth"]))
    assert "replication/cloth/kernels.py" in files  # imported through cloth.model
    assert "replication/cloth/__init__.py" in files
    assert not any(name.startswith("replication/motion/") for name in files)
    assert not any(name.startswith("replication/discrepancy/") for name in files)


def test_code_hash_depends_on_the_runner():
    cloth = provenance.code_hash("replication.experiments.bench.cloth:bench_cloth")
    assert cloth != provenance.code_hash("replication.experiments.motion:benchmark")
    assert cloth != provenance.code_hash()  # the whole package


def _package(tmp_path, monkeypatch, files):
    """A throw-away package ``replication`` under ``tmp_path`` made of ``files``."""
    package = tmp_path / "replication"
    for name, text in {"__init__.py": "", **files}.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text)
    monkeypatch.setattr(provenance, "PROJECT_ROOT", tmp_path)
    monkeypatch.setattr(provenance, "PACKAGE_DIR", package)
    monkeypatch.setattr(provenance, "CORE_MODULES", ())
    return package


RUNNER = ("from replication.sub import helper\n"
          "from replication import figure_a, figure_b\n\n\n"
          "def run():\n    return _draw(helper.X)\n\n\n"
          "def _draw(x):\n    return figure_a.plot(x)\n\n\n"
          "def other():\n    return figure_b.plot(1)\n")


def test_code_hash_follows_an_edit_of_an_imported_module(tmp_path, monkeypatch):
    package = _package(tmp_path, monkeypatch, {
        "sub/__init__.py": "", "sub/runner.py": RUNNER, "sub/helper.py": "X = 1\n",
        "figure_a.py": "def plot(x):\n    return x\n",
        "figure_b.py": "def plot(x):\n    return x\n", "other.py": "Y = 1\n"})
    before = provenance.code_hash("replication.sub.runner:run")
    (package / "other.py").write_text("Y = 2\n")
    assert provenance.code_hash("replication.sub.runner:run") == before
    # another runner's figure in the same module is no part of this runner's code
    (package / "figure_b.py").write_text("def plot(x):\n    return 2 * x\n")
    assert provenance.code_hash("replication.sub.runner:run") == before
    # its own figure, reached through a helper of its module, is
    (package / "figure_a.py").write_text("def plot(x):\n    return 2 * x\n")
    changed = provenance.code_hash("replication.sub.runner:run")
    assert changed != before
    (package / "sub" / "helper.py").write_text("X = 2\n")
    assert provenance.code_hash("replication.sub.runner:run") != changed


def test_a_pure_move_changes_no_code_hash(tmp_path, monkeypatch):
    package = _package(tmp_path, monkeypatch, {
        "sub/__init__.py": "", "sub/runner.py": RUNNER,
        "sub/helper.py": '"""Helper."""\nX = 1\n',
        "figure_a.py": "def plot(x):\n    return x\n",
        "figure_b.py": "def plot(x):\n    return x\n"})
    before = provenance.code_hash("replication.sub.runner:run")
    # the helper moves to another folder; the runner's import and a docstring follow
    (package / "sub" / "helper.py").unlink()
    (package / "lib").mkdir()
    (package / "lib" / "__init__.py").write_text("")
    (package / "lib" / "helper.py").write_text('"""Helper, moved."""\n\nX = 1  # same\n')
    (package / "sub" / "runner.py").write_text(
        RUNNER.replace("from replication.sub import helper", "from replication.lib import helper"))
    assert provenance.code_hash("replication.sub.runner:run") == before
    (package / "lib" / "helper.py").write_text("X = 3\n")
    assert provenance.code_hash("replication.sub.runner:run") != before


def test_splitting_a_module_changes_no_code_hash(tmp_path, monkeypatch):
    runner = "from replication import lib\n\n\ndef run():\n    return lib.f()\n"
    package = _package(tmp_path, monkeypatch, {
        "runner.py": runner, "lib.py": "X = 1\n\n\ndef f():\n    return X\n"})
    before = provenance.code_hash("replication.runner:run")
    (package / "lib.py").write_text('"""Now two modules."""\nfrom replication.part import X\n\n\n'
                                    "def f():\n    return X\n")
    (package / "part.py").write_text("X = 1\n")
    assert provenance.code_hash("replication.runner:run") == before
    (package / "part.py").write_text("X = 2\n")
    assert provenance.code_hash("replication.runner:run") != before


def test_a_runner_that_is_not_there_is_an_error(tmp_path, monkeypatch):
    _package(tmp_path, monkeypatch, {"sub/__init__.py": "", "sub/runner.py": RUNNER,
                                     "sub/helper.py": "X = 1\n",
                                     "figure_a.py": "", "figure_b.py": ""})
    with pytest.raises(ValueError, match="no top-level 'missing'"):
        provenance.code_hash("replication.sub.runner:missing")


def test_cache_keys_match_what_replicate_writes():
    entries = [entry for entry in experiment_entries() if entry[1] == "fig08_mesh"]
    configs = resolved_configs(["fig08_mesh"])
    prov, keys = experiment_keys(entries, configs)
    assert prov["fig08_mesh"]["config_sha256"] == provenance.config_hash(configs["fig08_mesh"])
    assert prov["fig08_mesh"]["code_sha256"] == provenance.code_hash(
        configs["fig08_mesh"]["runner"])
    assert set(keys) == {"fig08_mesh"}


def _sleeper(log, seconds=0.4, status=0):
    """A command that logs its start and end times, sleeps, and exits with ``status``."""
    def command_for(name):
        code = (f"import time; open({str(log)!r}, 'a').write(f'{name} start {{time.time()}}\\n');"
                f"time.sleep({seconds}); open({str(log)!r}, 'a').write("
                f"f'{name} end {{time.time()}}\\n'); raise SystemExit({status} if "
                f"{name!r} == 'bad' else 0)")
        return [sys.executable, "-c", code]
    return command_for


def _intervals(log):
    times = {}
    for line in log.read_text().splitlines():
        name, what, value = line.split()
        times.setdefault(name, {})[what] = float(value)
    return {name: (t["start"], t["end"]) for name, t in times.items()}


def _overlap(a, b):
    return a[0] < b[1] and b[0] < a[1]


def test_scheduler_respects_jobs_dependencies_and_exclusive(tmp_path, capsys):
    log = tmp_path / "log.txt"
    blocks = {"a": {}, "b": {}, "c": {"depends_on": ["a"]}, "bench": {"exclusive": True},
              "d": {}}
    outcome = run_scheduled(list(blocks), blocks, jobs=2, expected={"d": 100.0},
                            command_for=_sleeper(log, seconds=1.0), log_dir=tmp_path / "logs",
                            echo=False)
    assert all(code == 0 for code, _, _ in outcome.values())
    spans = _intervals(log)
    assert set(spans) == set(blocks)
    assert spans["c"][0] >= spans["a"][1]  # after its dependency
    for other in set(blocks) - {"bench"}:
        assert not _overlap(spans["bench"], spans[other])  # alone
    starts = sorted(spans.values())
    for i, span in enumerate(starts):  # never more than 2 at once
        assert sum(_overlap(span, other) for other in starts[i + 1:]) <= 1
    started = [line.split()[1] for line in capsys.readouterr().out.splitlines()
               if line.startswith("[start]")]
    assert started[0] == "d"  # the longest (by its expected seconds) starts first
    assert _overlap(spans["a"], spans["d"]) or _overlap(spans["b"], spans["d"])  # in parallel
    assert (tmp_path / "logs" / "a.log").exists()


def test_scheduler_skips_dependents_of_a_failure(tmp_path):
    log = tmp_path / "log.txt"
    blocks = {"bad": {}, "child": {"depends_on": ["bad"]}, "free": {}}
    outcome = run_scheduled(list(blocks), blocks, jobs=1, expected={},
                            command_for=_sleeper(log, seconds=0.05, status=3),
                            log_dir=tmp_path / "logs", echo=False)
    assert outcome["bad"][0] == 3
    assert outcome["child"][0] is None
    assert outcome["free"][0] == 0
    assert "child" not in _intervals(log)


def test_scheduler_refuses_a_dependency_cycle(tmp_path):
    blocks = {"a": {"depends_on": ["a"]}}
    start = time.time()
    with pytest.raises(RuntimeError, match="depends_on"):
        run_scheduled(["a"], blocks, jobs=1, expected={}, command_for=_sleeper(tmp_path / "l"),
                      log_dir=tmp_path, echo=False)
    assert time.time() - start < 5


def test_stale_experiments_follow_provenance_dependencies_and_cache(tmp_path):
    from replication.regenerate import stale_experiments
    from replication.results import write_json_atomic

    entries = [(1, "data", {}), (2, "study", {"depends_on": ["data"]}), (3, "other", {})]
    provenance = {name: {"config_sha256": name, "code_sha256": "c"} for _, name, _ in entries}
    keys = {name: f"key-{name}" for _, name, _ in entries}
    for _, name, _ in entries:
        write_json_atomic(tmp_path / name / "result.json", {"provenance": provenance[name]})
    assert stale_experiments(entries, tmp_path, provenance, keys, {}) == set()  # fresh clone
    assert stale_experiments(entries, tmp_path, provenance, keys, {},
                             force=True) == {"data", "study", "other"}
    changed = dict(provenance, data={"config_sha256": "new", "code_sha256": "c"})
    assert stale_experiments(entries, tmp_path, changed, keys, {}) == {"data", "study"}
    assert stale_experiments(entries, tmp_path, changed, keys, {}, cascade=False) == {"data"}
    # an earlier run recomputed "data" but stopped before "study": the cached key differs
    cache = {"study": {"key": "key-made-from-old-data"}}
    assert stale_experiments(entries, tmp_path, provenance, keys, cache) == {"study"}
    (tmp_path / "other" / "result.json").unlink()
    assert stale_experiments(entries, tmp_path, provenance, keys, {}) == {"other"}


def test_only_hashes_the_named_experiments_and_what_they_depend_on():
    """`--only` composes and hashes the named experiments and, transitively, those they
    depend on (a key holds its dependencies' keys), not all 30-odd (about 10 s)."""
    from replication.regenerate import with_dependencies

    blocks = {"data": {}, "fit": {"depends_on": ["data"]}, "study": {"depends_on": ["fit"]},
              "other": {}, "bench": {"depends_on": ["other"]}}
    assert with_dependencies({"study"}, blocks) == {"study", "fit", "data"}
    assert with_dependencies({"fit", "bench"}, blocks) == {"fit", "data", "bench", "other"}
    assert with_dependencies({"other"}, blocks) == {"other"}


def test_dry_run_names_the_dependency_that_runs_again(tmp_path):
    """A dependent current by its own provenance, whose cached key differs because an
    experiment it depends on runs again, is said to depend on that one, not to follow an
    interrupted run (which is said only when no dependency runs again)."""
    from replication.regenerate import _why_stale
    from replication.results import write_json_atomic

    blocks = {"data": {}, "study": {"depends_on": ["data"]}}
    provenance = {name: {"config_sha256": name, "code_sha256": "c"} for name in blocks}
    write_json_atomic(tmp_path / "study" / "result.json", {"provenance": provenance["study"]})

    def why(stale):
        return _why_stale("study", tmp_path, provenance, stale, stale, blocks, False)
    assert why({"data", "study"}) == "depends on data, which runs again"
    assert why({"study"}) == "an experiment it depends on was recomputed by an interrupted run"


def test_dependents_rerun_only_when_what_they_read_changed(tmp_path, capsys):
    log = tmp_path / "log.txt"
    blocks = {"data": {}, "same": {"depends_on": ["data"]}, "changed": {"depends_on": ["data"]}}
    asked = []

    def still_stale(name):
        asked.append(name)
        assert "data" in _intervals(log)   # asked once the dependency has finished
        return name == "changed"

    outcome = run_scheduled(list(blocks), blocks, jobs=2, expected={},
                            command_for=_sleeper(log, seconds=0.05), log_dir=tmp_path / "logs",
                            echo=False, recheck={"same", "changed"}, still_stale=still_stale)
    assert sorted(asked) == ["changed", "same"]
    assert outcome["same"][0] == "current" and outcome["changed"][0] == 0
    assert set(_intervals(log)) == {"data", "changed"}
    assert "same: up to date" in capsys.readouterr().out


def test_critical_paths_put_a_short_data_step_before_long_studies():
    from replication.regenerate import critical_paths

    blocks = {"data": {}, "study": {"depends_on": ["data"]}, "other": {}}
    paths = critical_paths(list(blocks), blocks, {"data": 1.0, "study": 100.0, "other": 50.0})
    assert paths == {"data": 101.0, "study": 100.0, "other": 50.0}


def test_shared_runs_wait_passively_unless_the_user_chose():
    from replication.workers import shared_threads

    assert shared_threads({}, 2)["OMP_WAIT_POLICY"] == "PASSIVE"
    assert "OMP_WAIT_POLICY" not in shared_threads({}, 1)
    assert shared_threads({"OMP_WAIT_POLICY": "ACTIVE"}, 2)["OMP_WAIT_POLICY"] == "ACTIVE"
    # each of the experiments run at once gets its share of the CPUs as numba threads
    assert shared_threads({}, 2, cpus=2)["NUMBA_NUM_THREADS"] == "1"
    assert shared_threads({}, 2, cpus=8)["NUMBA_NUM_THREADS"] == "4"
    assert shared_threads({}, 4, cpus=2)["NUMBA_NUM_THREADS"] == "1"
    assert "NUMBA_NUM_THREADS" not in shared_threads({}, 1, cpus=2)
    assert shared_threads({"NUMBA_NUM_THREADS": "2"}, 2, cpus=2)["NUMBA_NUM_THREADS"] == "2"
    # and as BLAS threads, which busy-wait beside another process whatever OpenMP's policy
    shared = shared_threads({}, 2, cpus=4)
    assert shared["OPENBLAS_NUM_THREADS"] == shared["OMP_NUM_THREADS"] == "2"


def test_worker_pools_share_the_cpus_and_restore_the_environment(monkeypatch):
    import os

    from replication.workers import process_pool

    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.setenv("NUMBA_NUM_THREADS", "1")
    with process_pool(2) as pool:
        seen = list(pool.map(os.getenv, ["OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"]))
    assert seen[0] == str(max(1, (os.cpu_count() or 1) // 2))
    assert seen[1] == "1"   # the user's value is kept
    assert "OPENBLAS_NUM_THREADS" not in os.environ


def test_kept_pools_hand_out_one_pool_until_the_block_ends(monkeypatch):
    import os

    import pytest

    from replication.workers import kept_pools, process_pool

    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    with kept_pools():
        with process_pool(2) as first:
            assert list(first.map(abs, [-1, -2])) == [1, 2]
        with process_pool(2) as second:
            assert second is first
        with kept_pools(), process_pool(2) as nested:   # a nested block uses the outer pools
            assert nested is first
        with process_pool(1) as other:
            assert other is not first
    with pytest.raises(RuntimeError):   # closed when the block ended
        first.submit(abs, -1)
    assert "OPENBLAS_NUM_THREADS" not in os.environ
    with process_pool(2) as fresh:
        assert fresh is not first


def _sleep_then(value):
    import time

    time.sleep(0.2)
    return value


def test_a_failing_pool_block_drops_its_queued_tasks():
    """An error inside the block (or Ctrl-C) cancels the tasks still queued instead of
    running them all before the error surfaces."""
    import time

    import pytest

    from replication.workers import process_pool

    with pytest.raises(RuntimeError, match="stop"):
        with process_pool(1) as pool:
            futures = [pool.submit(_sleep_then, i) for i in range(40)]
            assert futures[0].result() == 0
            start = time.perf_counter()   # after the worker's start-up, which load can slow
            raise RuntimeError("stop")
    assert sum(f.cancelled() for f in futures) > 30
    assert time.perf_counter() - start < 6   # the 39 tasks left would take 7.8 s


def test_moves_refuses_an_unknown_commit_in_one_line(capsys):
    from replication import moves

    assert moves.main(["no-such-commit"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: no-such-commit: not a commit") and err.count("\n") == 1


def test_dry_run_says_why_each_experiment_would_run_and_writes_nothing(tmp_path, capsys):
    """`replicate-all --dry-run` on a results folder of its own: one experiment without a
    result, one whose stored config hash differs; a refused --only makes no folder."""
    import json

    from replication.regenerate import main
    from replication.results import write_json_atomic

    results = tmp_path / "res"
    configs = resolved_configs(["fig08_mesh"])
    provenance_now, _ = experiment_keys(
        [e for e in experiment_entries() if e[1] == "fig08_mesh"], configs)
    changed = dict(provenance_now["fig08_mesh"], config_sha256="old")
    write_json_atomic(results / "fig08_mesh" / "result.json", {"provenance": changed})
    before = sorted(p.relative_to(results) for p in results.rglob("*"))
    assert main(["--dry-run", "--only", "fig08_mesh,cloth_reference",
                 "--results", str(results)]) == 0
    out = capsys.readouterr().out
    assert "fig08_mesh: would run (config changed;" in out
    assert "cloth_reference: would run (no result;" in out
    assert "2 experiment(s) would run" in out and "nothing was run or written" in out
    assert sorted(p.relative_to(results) for p in results.rglob("*")) == before
    assert json.loads((results / "fig08_mesh" / "result.json").read_text())[
        "provenance"]["config_sha256"] == "old"
    assert main(["--dry-run", "--force", "--only", "fig08_mesh",
                 "--results", str(results)]) == 0
    assert "fig08_mesh: would run (--force;" in capsys.readouterr().out
    assert main(["--only", "nope", "--results", str(tmp_path / "other")]) == 2
    assert not (tmp_path / "other").exists()


def test_every_report_block_names_its_part():
    from replication.report.build import PARTS

    parts = {name: block.get("part") for _, name, block in experiment_entries()}
    assert {name: part for name, part in parts.items() if part not in PARTS} == {}
    assert {part for part in parts.values()} == set(PARTS)


def test_part_selects_the_experiments_of_a_part_of_the_report(tmp_path, capsys):
    """`replicate-all --part paper` is `--only` with the experiments whose report.part is
    paper; a part that is not one, an empty list or --part with --only is one error line."""
    from replication.regenerate import main

    paper = sorted(name for _, name, block in experiment_entries()
                   if block.get("part") == "paper")
    assert "fig08_mesh" in paper and "cloth_baselines_budgets" not in paper
    assert main(["--dry-run", "--force", "--part", "paper",
                 "--results", str(tmp_path / "res")]) == 0
    out = capsys.readouterr().out
    running = sorted(line.split(":")[0] for line in out.splitlines() if ": would run" in line)
    assert running == paper
    assert f"{len(paper)} experiment(s) would run" in out
    for argv, message in ((["--part", "nope"], "--part='nope': expected PART[,PART] of "
                           "paper, baselines, validation, bench"),
                          (["--part", ","], "--part=',': expected PART"),
                          (["--part", "paper", "--only", "fig08_mesh"],
                           "--only and --part: give one of them")):
        assert main([*argv, "--results", str(tmp_path / "other")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"error: {message}") and err.count("\n") == 1, err
    assert not (tmp_path / "other").exists()


def test_the_committed_results_are_current():
    """README: a fresh clone recomputes nothing that its committed results hold. Every
    result of `replicate-all` carries the provenance (config, code and input hashes) that
    this config, code and data give now; a change to any of them, or a partial run
    (`--only`, `--part`) that rewrote files another experiment reads, shows here until
    `replicate-all` has brought the results up to date and they are committed."""
    from replication.regenerate import stale_now

    stale = stale_now(provenance.PROJECT_ROOT / "results")
    assert stale == [], (f"{len(stale)} committed result(s) no longer current: "
                         f"{', '.join(stale)} (`replicate-all --dry-run` says why)")
