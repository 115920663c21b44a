"""Sweeps, resume, gathering, and runs killed halfway."""

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

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
    assert gather_main([str(sweep)]) == 0
    rows = list(csv.DictReader(open(sweep / "results.csv")))
    assert [row["override.zoom"] for row in rows] == ["3", "4"]
    assert all(row["n_springs"] == "1566" for row in rows)


def test_gather_refuses_empty_folder(tmp_path):
    assert gather_main([str(tmp_path)]) == 2
    assert gather_main([str(tmp_path / "absent")]) == 2


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
