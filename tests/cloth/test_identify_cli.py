"""Identification experiments through the real command line and their refusals."""

import json

import numpy as np
import os
import subprocess
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from replication.cli import CONFIG_DIR, run_experiment
from replication.errors import InputError

ROOT = Path(__file__).resolve().parents[2]


def run_cli(*overrides):
    command = [str(ROOT / ".venv" / "bin" / "replicate"), *overrides]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run(command, cwd=ROOT, capture_output=True, text=True, env=env,
                          timeout=300)


def composed(name, *overrides):
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"experiment={name}", *overrides])
    return OmegaConf.to_container(cfg, resolve=True)


def test_identify_any_file_through_the_command_line(tmp_path):
    out = tmp_path / "out"
    done = run_cli("experiment=cloth_identify", f"out={out}", "budget=400",
                   f"data.path={ROOT / 'synthetic_data/cloth/reference_tau0.1.npz'}")
    assert done.returncode == 0, done.stderr
    result = json.loads((out / "result.json").read_text())
    assert set(result["best"]) == {"l01", "l23", "l45", "K", "tau", "cost"}
    assert result["population"][0]["cost"] == result["best"]["cost"]
    assert result["n_evals"] <= 400 and result["success"]


def test_ci_check_exits_non_zero_when_a_tolerance_is_violated(tmp_path):
    out = tmp_path / "out"
    done = run_cli("experiment=cloth_ci", f"out={out}", "method=paper_ea",
                   "ea.generations=1")
    assert done.returncode == 2
    error = done.stderr.split("\n")[0]
    assert error.startswith("error: cloth_ci (paper_ea, ") and "from the truth" in error
    # every parameter outside its tolerance is named, not only the first
    assert error.count("% from the truth") >= 2
    assert not (out / "result.json").exists()


def test_ci_check_fails_on_data_the_model_does_not_explain(tmp_path):
    """The reference played backwards: a frictionless cloth's parameters fit it, but the
    constraint acts out of order and the residuals are far above the noise."""
    arrays = dict(np.load("synthetic_data/cloth/reference_tau0.5.npz"))
    arrays["positions"] = arrays["positions"][::-1].copy()
    path = tmp_path / "reversed.npz"
    np.savez(path, **arrays)
    failed = run_cli("experiment=cloth_ci", f"out={tmp_path / 'a'}", f"data.path={path}")
    assert failed.returncode == 2 and not (tmp_path / "a" / "result.json").exists()
    assert "the data disagree with the model" in failed.stderr
    assert "at the true parameters" in failed.stderr and "% from the truth" not in failed.stderr
    unchecked = run_cli("experiment=cloth_ci", f"out={tmp_path / 'b'}", f"data.path={path}",
                        "check_misfit=false")
    assert unchecked.returncode == 0, unchecked.stderr
    result = json.loads((tmp_path / "b" / "result.json").read_text())
    assert result["passed"] and result["diagnostics"]["misfit"] > 3
    assert "truth_misfit" not in result    # not measured without the check
    reference = run_cli("experiment=cloth_ci", f"out={tmp_path / 'c'}")
    assert reference.returncode == 0, reference.stderr
    assert json.loads((tmp_path / "c" / "result.json").read_text())["truth_misfit"] < 3


@pytest.mark.parametrize("name, overrides, message", [
    ("cloth_identify", ["bounds.K=[5.0,1.0]"], "low >= high"),
    ("table1_2", ["ea.pop_size=3"], "population under 4"),
    ("table1_2", ["ea.keep=0.6"], "rates do not add up"),
    ("cloth_identify", ["cost.frame=600"], "outside the data"),
    ("cloth_baselines", ["cost.frame=500"], "outside the data"),
    ("cloth_ci", ["+tolerance.E=0.01"], "one per parameter"),
])
def test_bad_input_is_refused_before_anything_is_written(tmp_path, name, overrides,
                                                         message):
    out = tmp_path / "out"
    config = composed(name, *overrides, f"out={out}", f"figure_dir={tmp_path / 'fig'}")
    with pytest.raises(InputError, match=message):
        run_experiment(config, out)
    assert not (out / "result.json").exists() and not (tmp_path / "fig").exists()


def test_baselines_study_times_the_cost_apart_from_the_optimisers(tmp_path):
    # one seed of three optimisers on one reference: each run's time inside the cost is
    # measured, is part of the run's time, and sums per optimiser into the summary
    config = composed("cloth_baselines", "n_seeds=1", "budgets=[60,120]", "workers=1",
                      f"data.path={ROOT / 'synthetic_data/cloth/reference_tau0.5.npz'}",
                      f"out={tmp_path / 'out'}",
                      f"figure_dir={tmp_path / 'fig'}")
    config["optimisers"] = [entry for entry in config["optimisers"]
                            if entry["name"] in ("paper EA", "pymoo Nelder-Mead")
                            or entry["kind"] == "least_squares"]
    result = run_experiment(config, tmp_path / "out")
    assert list(result["runs"]) == ["reference_tau0.5"]
    for name, runs in result["runs"]["reference_tau0.5"].items():
        summary = result["summary"]["reference_tau0.5"][name]
        for run in runs:
            assert 0.0 < run["objective_cpu_seconds"] < run["run_cpu_seconds"], name
        for key in ("objective_cpu_seconds", "run_cpu_seconds", "run_seconds"):
            assert summary[key] == sum(r[key] for r in runs), key
