"""The real command line on a small sequence, and every motion config composes."""

import re
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir

from replication.cli import CONFIG_DIR
from replication.motion.io import write_sequence_npz
from replication.report.motion import single_section

ROOT = Path(__file__).resolve().parents[2]
REPLICATE = ROOT / ".venv" / "bin" / "replicate"
MOTION_CONFIGS = ["motion_data", "motion_single", "motion_accuracy", "bench_motion"]


def run(*args):
    command = [str(REPLICATE)] if REPLICATE.exists() else [sys.executable, "-m",
                                                            "replication.cli"]
    return subprocess.run([*command, *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("name", MOTION_CONFIGS)
def test_config_composes(name):
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"experiment={name}"])
    assert cfg.name == name and re.match(r"replication\.experiments\.motion(_single)?:", cfg.runner)


def test_single_rotation_command_line(tmp_path, small_sequence):
    frames, labels, truth = small_sequence
    write_sequence_npz(tmp_path / "seq.npz", frames, labels=labels, truth=truth)
    out = tmp_path / "out"
    done = run("experiment=motion_single", f"data.path={tmp_path / 'seq.npz'}", f"out={out}",
               "method.omega_count=40")
    assert done.returncode == 0, done.stderr
    result = json.loads((out / "result.json").read_text())
    assert set(result["irc"]) == {"xi", "eta", "omega", "peak"}
    assert result["errors"]["refined"]["centre_px"] < 1.0
    assert len(result["sweep"]["omega"]) == 40
    # figures of a given sequence go beside its result, never over the paper's figures
    assert len(result["figures"]) == 4
    assert all(Path(p).exists() and Path(p).parent == out / "figures" for p in result["figures"])
    assert "| truth |" in single_section(result).markdown


def test_bad_sequence_exits_2_without_result(tmp_path):
    np.savez(tmp_path / "one.npz", frames=np.random.default_rng(0).random((1, 16, 16)))
    out = tmp_path / "out"
    done = run("experiment=motion_single", f"data.path={tmp_path / 'one.npz'}", f"out={out}")
    assert done.returncode == 2
    assert done.stderr.strip().splitlines()[-1].startswith("error: ")
    assert "expected T >= 2 frames" in done.stderr
    assert not (out / "result.json").exists()


def test_bad_setting_exits_2(tmp_path):
    done = run("experiment=motion_single", f"out={tmp_path / 'out'}", "+method.nosuch=1")
    assert done.returncode == 2
    assert "method: unknown setting(s) ['nosuch']" in done.stderr
