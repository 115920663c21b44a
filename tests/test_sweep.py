"""Sweeps, resume, gathering, and runs killed halfway."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from replication.sweep import (
    excluded_keys,
    gather,
    inputs_of,
    median_by_x,
    overrides_of,
    run_overrides,
    series,
    sweep_warnings,
)
from replication.sweep import main as gather_main
from tests.test_cli import ROOT, run_cli


def test_multirun_resume_and_gather(tmp_path):
    sweep = tmp_path / "sweep"
    args = ["-m", "experiment=fig08_mesh", f"figure_dir={tmp_path / 'f'}", "zoom=3,4",
            f"hydra.sweep.dir={sweep}"]
    done = run_cli(*args)
    assert done.returncode == 0, done.stderr
    results = sorted(sweep.rglob("result.json"))
    assert [p.parent.name.split(",")[-1] for p in results] == ["zoom=3", "zoom=4"]
    before = [p.read_text() for p in results]
    again = run_cli(*args, "resume=true")
    assert again.returncode == 0, again.stderr
    assert again.stderr.count("up to date") == 2
    assert [p.read_text() for p in results] == before
    # progress output, force and the limits change no result, so they name no folder:
    # resumed, not redone
    quiet = run_cli(*args, "resume=true", "progress=none", "force=true",
                    "limits.max_seconds=600")
    assert quiet.returncode == 0, quiet.stderr
    assert sorted(sweep.rglob("result.json")) == results
    assert [p.read_text() for p in results] == before
    assert gather_main([str(sweep)]) == 0
    rows = list(csv.DictReader(open(sweep / "results.csv")))
    assert [row["override.zoom"] for row in rows] == ["3", "4"]
    assert all(row["n_springs"] == "1566" for row in rows)
    # the gatherer compares the runs with the last sweep (multirun.yaml): a job without a
    # result, and a result of another sweep into the same folder, are warned
    from replication.sweep import expected_runs, sweep_warnings

    names = sorted(p.parent.name for p in results)
    assert expected_runs(sweep) == set(names)
    assert sweep_warnings(sweep, names) == []
    warnings = sweep_warnings(sweep, [names[0], "zoom=9"])
    assert len(warnings) == 2 and "1 of the 2 jobs" in warnings[0] and "zoom=9" in warnings[1]
    # another subdir than the suite's: nothing can be told
    text = (sweep / "multirun.yaml").read_text()
    (sweep / "multirun.yaml").write_text(text.replace(
        "subdir: ${folder_name:${hydra.job.override_dirname}}", "subdir: ${hydra.job.num}"))
    assert expected_runs(sweep) is None


def test_gather_refuses_empty_folder(tmp_path, capsys):
    assert gather_main([str(tmp_path)]) == 2
    assert gather_main([str(tmp_path / "absent")]) == 2
    (tmp_path / "notes.txt").write_text("x")
    capsys.readouterr()
    assert gather_main([str(tmp_path / "notes.txt")]) == 2
    assert "notes.txt: is a file; expected a sweep folder" in capsys.readouterr().err
    sweep = fake_sweep(tmp_path / "sweep", sweep_metrics=["best.cost"])
    assert gather_main([str(sweep), "--output", str(tmp_path / "absent" / "x.csv")]) == 2
    assert f"no folder {tmp_path / 'absent'}" in capsys.readouterr().err
    # a single run's folder (its result.json in it) is not a sweep: refused, not gathered
    run = next(sweep.rglob("result.json")).parent
    capsys.readouterr()
    assert gather_main([str(run)]) == 2 and not (run / "results.csv").exists()
    assert "a single run's folder" in capsys.readouterr().err
    assert gather_main([str(sweep), "--no-plots"]) == 0
    assert (sweep / "results.csv").exists() and not list(sweep.glob("*.png"))
    assert gather_main([str(sweep)]) == 0 and list(sweep.glob("*.png"))   # plots by default


def fake_sweep(folder, sweep_metrics=None):
    """A sweep folder of result.json files: budget x method x seed, cost = f(budget, seed)."""
    for budget in (100, 300, 1000):
        for method in ("ea", "structured"):
            for seed in (0, 1, 2):
                run = folder / f"budget={budget},method={method},seed={seed}"
                run.mkdir(parents=True)
                cost = 1000.0 / budget * (1 + seed) * (2 if method == "ea" else 1)
                config = {"sweep_metrics": sweep_metrics} if sweep_metrics else {}
                run.joinpath("result.json").write_text(json.dumps({
                    "experiment": "fake", "config": config, "seed": seed,
                    "best": {"cost": cost, "method": method}, "n_evals": budget}))
    return folder


def test_overrides_of_a_folder_nested_by_a_slash_in_a_value():
    run = Path("budget=100,figure_dir=") / "tmp" / "f,seed=2"
    assert overrides_of(run) == {"override.budget": "100", "override.figure_dir": "/tmp/f",
                                 "override.seed": "2"}


def test_median_by_x_takes_the_median_of_each_x_sorted():
    pairs = [(3.0, 5.0), (1.0, 2.0), (3.0, 1.0), (1.0, 4.0), (3.0, 9.0)]
    assert median_by_x(pairs) == [(1.0, 3.0), (3.0, 5.0)]
    assert median_by_x([("b", 1.0), ("a", 2.0)]) == [("a", 2.0), ("b", 1.0)]


def test_series_groups_by_the_other_overrides_and_takes_medians_over_seeds(tmp_path):
    rows = gather(fake_sweep(tmp_path))
    numeric, lines = series(rows, "best.cost", "override.budget")
    assert numeric and [line["label"] for line in lines] == ["method=ea", "method=structured"]
    assert len(lines[0]["points"]) == 9  # every run is a point
    # median over seeds 0, 1, 2 of 1000 / budget * (1 + seed) * 2 is at seed 1
    assert lines[0]["median"] == [(100.0, 40.0), (300.0, 4000 / 300), (1000.0, 4.0)]
    assert lines[1]["median"] == [(100.0, 20.0), (300.0, 2000 / 300), (1000.0, 2.0)]
    categorical, by_method = series(rows, "best.cost", "override.method")
    assert not categorical and [line["label"] for line in by_method] == [
        "budget=100", "budget=300", "budget=1000"]
    assert by_method[0]["median"] == [("ea", 40.0), ("structured", 20.0)]


def test_gather_plots_the_configured_metrics_deterministically(tmp_path, capsys):
    sweep = fake_sweep(tmp_path / "sweep", sweep_metrics=["best.cost", "n_evals"])
    assert gather_main([str(sweep)]) == 0
    plots = sorted(p.name for p in sweep.glob("*.png"))
    assert plots == ["sweep_best.cost_vs_budget.png", "sweep_n_evals_vs_budget.png"]
    first = (sweep / plots[0]).read_bytes()
    assert gather_main([str(sweep)]) == 0
    assert (sweep / plots[0]).read_bytes() == first


def test_metric_and_x_options_and_categorical_axis(tmp_path):
    sweep = fake_sweep(tmp_path / "sweep")
    assert gather_main([str(sweep), "--metric", "best.cost", "--x", "method"]) == 0
    assert [p.name for p in sweep.glob("*.png")] == ["sweep_best.cost_vs_method.png"]


def test_no_metric_gives_a_hint_and_no_plot(tmp_path, capsys):
    sweep = fake_sweep(tmp_path / "sweep")
    assert gather_main([str(sweep)]) == 0
    hint = capsys.readouterr().out.splitlines()[-1]
    assert hint.startswith("no plots:") and "best.cost" in hint and "n_evals" in hint
    assert not list(sweep.glob("*.png"))


@pytest.mark.parametrize("args, message", [
    (["--metric", "best.nope"], "error: metric 'best.nope': not a column"),
    (["--metric", "best.method"], "error: metric 'best.method': not a numeric column"),
    (["--metric", "best.cost", "--x", "zoom"], "error: --x zoom: not an override"),
])
def test_unknown_metric_or_override_exits_2(tmp_path, capsys, args, message):
    sweep = fake_sweep(tmp_path / "sweep")
    assert gather_main([str(sweep), *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith(message) and err.count("\n") == 1
    assert not list(sweep.glob("*.png")) and not (sweep / "results.csv").exists()


def test_configured_metric_absent_from_the_results_is_skipped_with_a_note(tmp_path, capsys):
    sweep = fake_sweep(tmp_path / "sweep", sweep_metrics=["best.absent", "n_evals"])
    assert gather_main([str(sweep)]) == 0
    assert "sweep_metrics: best.absent is not a numeric column" in capsys.readouterr().out
    assert [p.name for p in sweep.glob("*.png")] == ["sweep_n_evals_vs_budget.png"]


def test_run_killed_halfway_leaves_no_result(tmp_path):
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    process = subprocess.Popen(
        [sys.executable, "-m", "replication.cli", "experiment=fig11_reconstruction",
         f"out={out}", f"figure_dir={tmp_path / 'f'}"],
        cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 60
    while time.time() < deadline:  # wait until the run is under way, then kill it
        if out.exists() and process.poll() is None:
            break
        time.sleep(0.05)
    time.sleep(1.0)
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert not (out / "result.json").exists()
    assert not [p for p in Path(out).iterdir() if p.name.startswith(".result.json")]


def test_every_limit_is_left_out_of_sweep_folder_names():
    """Hydra leaves a key out of run-folder names only by its full key: each limit is
    listed (a new limit must be too)."""
    from omegaconf import OmegaConf

    from replication.guard import DEFAULT_LIMITS

    excluded = OmegaConf.load(ROOT / "configs" / "config.yaml").hydra.job.config\
        .override_dirname.exclude_keys
    assert {f"limits.{key}" for key in DEFAULT_LIMITS} <= set(excluded)


def test_a_path_value_gives_one_run_folder_read_back_by_the_gatherer():
    """A sweep over data.path=dir/a.npz,... nested its run folders at each '/'."""
    from replication.cli import folder_name

    name = folder_name("data.path=mine/data/k4%.npz,seed=0")
    assert "/" not in name
    assert overrides_of(name) == {"override.data.path": "mine/data/k4%.npz",
                                  "override.seed": "0"}


def write_result(folder, **result):
    """A hand-written ``result.json`` in ``folder`` (made with its parents)."""
    folder.mkdir(parents=True)
    (folder / "result.json").write_text(json.dumps({"experiment": "fake", **result}))


def test_overrides_of_splits_outside_brackets_and_quotes_and_unquotes():
    assert overrides_of("+cost.frames=[150,200],seed=0") == {
        "override.+cost.frames": "[150,200]", "override.seed": "0"}
    assert overrides_of("data.path='%2Fa b%2Fc,1.npz',name='hello world',seed=0") == {
        "override.data.path": "/a b/c,1.npz", "override.name": "hello world",
        "override.seed": "0"}
    assert overrides_of("name=b\\,c,seed=0") == {"override.name": "b,c", "override.seed": "0"}
    # brackets that do not pair up: split at every comma, as before
    assert overrides_of("a=[1,b=2") == {"override.a": "[1", "override.b": "2"}


def hydra_jobs(arguments, exclude_keys):
    """``[(folder name, job overrides)]`` of a sweep as Hydra's basic sweeper and the
    suite's ``hydra.sweep.subdir`` make them (the overrides a result's ``overrides`` holds)."""
    from hydra._internal.config_loader_impl import get_overrides_dirname
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from replication.cli import folder_name

    parser = OverridesParser.create()
    [batch] = BasicSweeper.split_arguments(parser.parse_overrides(arguments), None)
    return [(folder_name(get_overrides_dirname(parser.parse_overrides(job), exclude_keys,
                                               ",", "=")), job) for job in batch]


def test_a_results_overrides_list_keeps_values_with_commas_apart(tmp_path):
    exclude = excluded_keys(tmp_path)  # no multirun.yaml: configs/config.yaml's
    assert {"experiment", "out", "limits.max_seconds"} <= exclude
    jobs = hydra_jobs(["experiment=fake", "+cost.frames=[150,200],[150,300]",
                       "data.path='/a b/c,1.npz'", "numerics.damping=null,1.0e-05",
                       "init.rest_spread=0.0", "limits.max_seconds=60"], list(exclude))
    assert len(jobs) == 4
    for name, job in jobs:
        write_result(tmp_path / name, overrides=job, best={"cost": 1.0})
    rows = gather(tmp_path)
    assert sorted(row["override.+cost.frames"] for row in rows) == [
        "[150,200]", "[150,200]", "[150,300]", "[150,300]"]
    assert {row["override.data.path"] for row in rows} == {"/a b/c,1.npz"}
    assert sorted(row["override.numerics.damping"] for row in rows) == [
        "1e-05", "1e-05", "null", "null"]   # as Hydra writes the swept value
    # the excluded keys are left out, as from the folder names; no overrides.N columns
    columns = {key for row in rows for key in row}
    assert {key for key in columns if key.startswith("override")} == {
        "override.+cost.frames", "override.data.path", "override.init.rest_spread",
        "override.numerics.damping"}
    # a result without the list (an older one) gives the same from its folder name
    for name, job in jobs:
        assert overrides_of(name) == run_overrides(name, {"overrides": job}, exclude)


def test_a_result_without_overrides_reads_its_folder_name(tmp_path):
    write_result(tmp_path / "cost.kind=full,seed=1", seed=1)
    write_result(tmp_path / "cost.kind=small,seed=0", seed=0,
                 overrides=["experiment=fake", "cost.kind=small", "seed=0"])
    rows = gather(tmp_path)
    assert [(row["override.cost.kind"], row["override.seed"]) for row in rows] == [
        ("full", "1"), ("small", "0")]


def test_sweep_warnings_read_encoded_folder_names_as_they_are(tmp_path):
    """A swept value with '/' or '%': the run folders are %2F / %25 already."""
    (tmp_path / "multirun.yaml").write_text("""hydra:
  sweep: {dir: x, subdir: '${folder_name:${hydra.job.override_dirname}}'}
  sweeper: {_target_: hydra._internal.core_plugins.basic_sweeper.BasicSweeper}
  job: {config: {override_dirname: {kv_sep: '=', item_sep: ',', exclude_keys: [experiment]}}}
  overrides: {task: ['experiment=fake', 'data.path=a/b.npz,a/c%.npz', 'seed=0']}
""")
    names = ["data.path=a%2Fb.npz,seed=0", "data.path=a%2Fc%25.npz,seed=0"]
    for name in names:
        write_result(tmp_path / name, seed=0)
    assert sweep_warnings(tmp_path, names) == []
    assert sweep_warnings(tmp_path, [Path(name) for name in names]) == []
    assert [row["override.data.path"] for row in gather(tmp_path)] == ["a/b.npz", "a/c%.npz"]
    # a sweep made before '/' was written %2F nested its folders: the same names
    assert sweep_warnings(tmp_path, [Path("data.path=a") / "b.npz,seed=0", names[1]]) == []
    [missing] = sweep_warnings(tmp_path, names[:1])
    assert "1 of the 2 jobs" in missing and names[1] in missing


def test_gather_skips_result_files_below_hidden_folders(tmp_path):
    sweep = fake_sweep(tmp_path / "sweep")
    staged = sweep / ".result.json.partial-x1" / "out"   # a run killed during its commit
    write_result(staged, seed=0, best={"cost": 0.0})
    write_result(sweep / ".submitit" / "1", seed=0)
    rows = gather(sweep)
    assert len(rows) == 18 and not any(row["run"].startswith(".") for row in rows)


def test_gather_refuses_to_write_its_csv_onto_a_result_json(tmp_path, capsys):
    sweep = fake_sweep(tmp_path / "sweep")
    run = sweep / "budget=100,method=ea,seed=0" / "result.json"
    before = run.read_text()
    assert gather_main([str(sweep), "--output", str(run), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: --output {run}: a run's result") and err.count("\n") == 1
    assert run.read_text() == before
    new = sweep / "result.json"   # would be gathered as a run next time
    assert gather_main([str(sweep), "--output", str(new), "--no-plots"]) == 2
    assert not new.exists() and "expected a CSV file path" in capsys.readouterr().err


def test_inputs_of_runs_reading_different_files_share_one_column(tmp_path):
    sha = {"d/a.npz": "a" * 64, "d/b;c.npz": "b" * 64, "ref.npz": "c" * 64}
    write_result(tmp_path / "data.path=d%2Fa.npz", provenance={
        "code_sha256": "x", "inputs_sha256": {"d/a.npz": sha["d/a.npz"]}})
    write_result(tmp_path / "data.path=d%2Fb;c.npz", provenance={
        "code_sha256": "x", "inputs_sha256": {"d/b;c.npz": sha["d/b;c.npz"],
                                              "ref.npz": sha["ref.npz"]}})
    rows = gather(tmp_path)
    assert [row["provenance.inputs_sha256"] for row in rows] == [
        f"d/a.npz:{sha['d/a.npz']}", f"d/b;c.npz:{sha['d/b;c.npz']};ref.npz:{sha['ref.npz']}"]
    assert not [key for row in rows for key in row if key.startswith("provenance.inputs_")
                and key != "provenance.inputs_sha256"]
    assert inputs_of(rows[1]) == {"d/b;c.npz": sha["d/b;c.npz"], "ref.npz": sha["ref.npz"]}
    # runs reading the same files keep one column per file (the committed CSVs' form)
    same = tmp_path / "same"
    for seed in (0, 1):
        write_result(same / f"seed={seed}", provenance={"inputs_sha256": {"ref.npz": sha[
            "ref.npz"]}})
    rows = gather(same)
    assert [row["provenance.inputs_sha256.ref.npz"] for row in rows] == [sha["ref.npz"]] * 2
    assert inputs_of(rows[0]) == {"ref.npz": sha["ref.npz"]}
