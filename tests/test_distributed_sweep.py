"""Sweeps through distributed engines gather to the serial sweep's CSV.

The same small sweep (the paper's EA on the tau = 0.5 reference, 300 evaluations, seeds 0 to
2: seed-dependent floating-point answers, about a second per run) runs serially, through
hydra-submitit-launcher's ``submitit_local`` (one process per job, the code path of
``submitit_slurm``), and through the suite's Dask launcher (``hydra/launcher=dask``), once on
a cluster this test starts with the commands docs/results.md gives for a real one
(``dask scheduler``, ``dask worker``, both on 127.0.0.1, 2 worker processes of one thread)
and once on the local cluster the launcher starts itself. ``replicate-gather`` must give the
same CSV each time, except the columns in ``VARIES``. A sweep with a refused job ends with
status 2 on the Dask launcher, as it does serially.

Marked ``distributed`` (``pytest -m "not distributed"`` leaves it out): 40 to 50 s on two
busy cores."""

import contextlib
import csv
import json
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from replication.sweep import main as gather_main
from tests.test_cli import ROOT, run_cli

pytestmark = pytest.mark.distributed

SWEEP = ["experiment=cloth_identify", "method=paper_ea", "budget=300", "seed=0,1,2"]
# wall_seconds is each run's measured time, never the same twice; every other column (the
# run folder, overrides, seed, every number of the answer) must match exactly
VARIES = {"wall_seconds"}


def run_sweep(folder, *launcher):
    """Run the sweep into ``folder`` with the given launcher overrides; returns its stderr.
    A sweep that does not end fails the test with its stderr (what the workers logged)."""
    try:
        done = run_cli("-m", *SWEEP, *launcher, f"hydra.sweep.dir={folder}")
    except subprocess.TimeoutExpired as hung:
        stderr = hung.stderr.decode(errors="replace") if hung.stderr else ""
        pytest.fail(f"the sweep did not end within {hung.timeout} s; its stderr:\n"
                    f"{stderr[-6000:]}")
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stderr


def gathered(folder):
    """``replicate-gather`` of the sweep in ``folder``: (header, rows) of its CSV, rows
    without the ``VARIES`` columns."""
    assert gather_main([str(folder)]) == 0
    with open(folder / "results.csv", newline="") as handle:
        reader = csv.DictReader(handle)
        rows = list(reader)
    assert len(rows) == 3 and all(float(row["wall_seconds"]) > 0 for row in rows)
    return reader.fieldnames, [{k: v for k, v in row.items() if k not in VARIES}
                               for row in rows]


def swept_and_plain(tmp_path, study, seeds, launcher, plain_only=()):
    """Sweep ``study`` over ``seeds`` (the first value is 3) through ``launcher``, and run it
    plainly with seed 3 (and the overrides ``plain_only``); returns the two ``result.json``
    paths of seed 3 and the sweep's stderr."""
    folder = tmp_path / "sweep"
    done = run_cli("-m", *study, *seeds, *launcher, f"hydra.sweep.dir={folder}")
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Traceback" not in done.stderr
    plain = run_cli(*study, "seed=3", *plain_only, f"out={tmp_path / 'plain'}")
    assert plain.returncode == 0, plain.stderr[-3000:]
    (swept,) = [p for p in folder.rglob("result.json") if "seed=3" in p.parent.name
                or p.parent == folder]
    return swept, tmp_path / "plain" / "result.json", done.stderr


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    folder = tmp_path_factory.mktemp("serial") / "sweep"
    run_sweep(folder)
    return gathered(folder)


def _dask_command(name):
    script = shutil.which("dask", path=str(Path(sys.executable).parent)) or \
        shutil.which("dask")
    assert script, "the dask command (package dask) is not installed"
    return [script, name]


@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory):
    """A scheduler and 2 one-thread workers on 127.0.0.1, started as a user would on real
    machines; yields the scheduler file the launcher is pointed at and its address."""
    tmp_path = tmp_path_factory.mktemp("dask")
    scheduler_file = tmp_path / "scheduler.json"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    processes, logs = [], []

    def start(command):
        logs.append(open(tmp_path / f"{command[1]}.log", "w"))
        processes.append(subprocess.Popen(command, cwd=ROOT, env=env, stdout=logs[-1],
                                          stderr=subprocess.STDOUT, start_new_session=True))

    try:
        start(_dask_command("scheduler") + [
            "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
            "--scheduler-file", str(scheduler_file)])
        deadline = time.time() + 60
        while not scheduler_file.exists() and time.time() < deadline:
            time.sleep(0.1)
        start(_dask_command("worker") + [
            "--scheduler-file", str(scheduler_file), "--host", "127.0.0.1",
            "--nworkers", "2", "--nthreads", "1", "--no-dashboard",
            "--local-directory", str(tmp_path / "dask-worker")])
        from distributed import Client

        with Client(scheduler_file=str(scheduler_file), timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
            address = client.scheduler.address
        yield scheduler_file, address
    finally:
        for process in reversed(processes):  # the workers first, then the scheduler
            try:
                os.killpg(process.pid, signal.SIGTERM)
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
            except ProcessLookupError:
                pass
        for log in logs:
            log.close()


def test_submitit_local_sweep_gathers_to_the_serial_csv(tmp_path, serial):
    folder = tmp_path / "sweep"
    run_sweep(folder, "hydra/launcher=local")
    assert (folder / ".submitit").is_dir()  # the jobs did go through submitit
    assert gathered(folder) == serial


def test_dask_sweep_on_a_running_cluster_gathers_to_the_serial_csv(tmp_path, serial,
                                                                    dask_cluster):
    scheduler_file, address = dask_cluster
    folder = tmp_path / "sweep"
    # in two batches: each launch connects again (the first one's client is closed)
    err = run_sweep(folder, "hydra/launcher=dask", f"hydra.launcher.address={scheduler_file}",
                    "hydra.sweeper.max_batch_size=2")
    assert f"dask launcher: 2 jobs on {address}" in err
    assert f"dask launcher: 1 jobs on {address}" in err
    assert gathered(folder) == serial


def test_dask_sweep_on_its_own_local_cluster_gathers_to_the_serial_csv(tmp_path, serial):
    """Also with Dask's default HTTP port (8787) taken, as when another cluster runs on the
    machine: the local cluster used to warn "Port 8787 is already in use"."""
    folder = tmp_path / "sweep"
    with contextlib.ExitStack() as stack:
        with contextlib.suppress(OSError):  # taken already: as good
            taken = stack.enter_context(socket.socket())
            taken.bind(("0.0.0.0", 8787))
            taken.listen()
        err = run_sweep(folder, "hydra/launcher=dask")
    assert "dask launcher: 3 jobs on tcp://127.0.0.1:" in err
    assert "already in use" not in err, err
    assert gathered(folder) == serial


def test_dask_job_of_an_experiment_with_worker_processes_runs_its_tasks_itself(tmp_path):
    """A Dask worker is a daemonic process, which may not start processes: a job of an
    experiment with worker processes (discrepancy_outside, study.workers=2) ended in
    multiprocessing's "daemonic processes are not allowed to have children" traceback. Its
    datasets now run in the worker itself, with the answers of a plain run's (each dataset
    is seeded alone, so a plain run in one process gives the answers of its pool: the
    comparison needs no pool of its own)."""
    study = ["experiment=discrepancy_outside", "study.n_datasets=2",
             "study.frames_range=[100,120]", "figure=null", "manifest=null"]
    swept, plain, err = swept_and_plain(tmp_path, study, ["seed=3"], ["hydra/launcher=dask"],
                                        plain_only=["study.workers=1"])
    assert "is a daemon" in err   # the tasks ran in the worker

    def datasets(path):
        rows = json.loads(path.read_text())["datasets"]
        return [{k: v for k, v in row.items() if k != "wall_seconds"} for row in rows]
    assert datasets(swept) == datasets(plain)


def test_dask_launcher_closes_its_local_cluster_without_the_shutdown_noise(capfd):
    """A worker's heartbeat in flight while the local cluster's scheduler closed logged a
    CommClosedError traceback ("Failed to communicate with scheduler during heartbeat") on
    a sweep whose jobs had all succeeded (a race: CI saw it once in about ten runs). Here a
    worker plugin logs such an error as each worker closes, every time: a plain close shows
    it on stderr, the launcher's close does not, and leaves this process's logging as it
    was."""
    from distributed import Client, LocalCluster
    from distributed.diagnostics.plugin import WorkerPlugin

    from hydra_plugins.replication_dask_launcher.dask_launcher import close_quietly

    class LogsWhenClosing(WorkerPlugin):
        def teardown(self, worker):
            logging.getLogger("distributed.worker").error(
                "Failed to communicate with scheduler during heartbeat (test)")

    def closed(close):
        cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=":0")
        client = Client(cluster)
        client.register_plugin(LogsWhenClosing())
        capfd.readouterr()
        close(client, cluster)
        time.sleep(0.5)  # the worker process's last lines
        return capfd.readouterr().err

    def plainly(client, cluster):
        client.close()
        cluster.close()

    level = logging.getLogger("distributed").level
    assert "during heartbeat (test)" in closed(plainly)  # the noise is there to hide
    assert "during heartbeat (test)" not in closed(close_quietly)
    assert logging.getLogger("distributed").level == level


def test_dask_sweep_with_a_failing_job_exits_2_and_keeps_the_other_jobs(tmp_path,
                                                                      dask_cluster):
    """A refused job (README.md is no trajectory) fails the sweep with one error line
    naming it and status 2, as the serial sweep does; unlike it, the other jobs still run."""
    scheduler_file, _ = dask_cluster
    folder = tmp_path / "sweep"
    done = run_cli("-m", "experiment=cloth_identify", "method=paper_ea", "budget=50",
                   "data.path=README.md,synthetic_data/cloth/reference_tau0.5.npz",
                   "hydra/launcher=dask", f"hydra.launcher.address={scheduler_file}",
                   f"hydra.sweep.dir={folder}")
    assert done.returncode == 2, done.stderr[-3000:]
    # workers started before the sweep (as on a real cluster) did not inherit the sweep's
    # REPLICATION_SWEEP: the launcher passes it with each job, so the refused job leaves
    # its note and the sweep ends with replicate's summary line; the launcher shows the
    # job's own error line from the worker's stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 2 and "README.md: cannot be read" in errors[0], done.stderr
    assert errors[1].startswith("error: 1 job(s) of the sweep refused") and \
        "README.md: cannot be read" in errors[1] and "resume=true" in errors[1], done.stderr
    assert "Error executing job" not in done.stderr, done.stderr
    runs = [p.parent.relative_to(folder).as_posix() for p in folder.rglob("result.json")]
    assert runs == ["budget=50,data.path=synthetic_data%2Fcloth%2Freference_tau0.5.npz,"
                    "method=paper_ea"]
    assert not (folder / "budget=50,data.path=README.md,method=paper_ea").exists()


def test_a_job_whose_result_cannot_be_sent_back_comes_back_failed_with_its_story():
    """A result Dask cannot pickle never reached the client (the worker logged "Failed to
    serialize" and the sweep waited for ever, twice in CI): the worker now sends the job
    back as failed with what could not be sent."""
    import threading

    from hydra.core.utils import JobReturn, JobStatus

    from hydra_plugins.replication_dask_launcher.dask_launcher import sendable

    fine = JobReturn(overrides=["seed=1"], status=JobStatus.COMPLETED, _return_value=None)
    assert sendable(fine, "tail", 3) == (fine, "tail")
    stuck = JobReturn(overrides=["seed=2"], status=JobStatus.FAILED,
                      _return_value=ValueError("bad", threading.Lock()))
    ret, tail = sendable(stuck, "tail", 4)
    assert tail == "tail" and ret.status == JobStatus.FAILED and ret.overrides == ["seed=2"]
    assert isinstance(ret._return_value, RuntimeError)
    message = str(ret._return_value)
    assert message.startswith("job 4: its result cannot be sent back from the Dask worker")
    assert "ValueError: ('bad', <unlocked _thread.lock" in message


def test_a_job_that_raises_on_the_worker_comes_back_failed_with_its_traceback(tmp_path):
    """Whatever a job raises outside the experiment (here: a worker that cannot see the
    folder the sweep was submitted from) comes back as a failed job holding the traceback
    as text, which always pickles."""
    from hydra.core.utils import JobStatus

    from hydra_plugins.replication_dask_launcher.dask_launcher import SweepState, run_one_job

    state = SweepState(hydra_context=None, task_function=None, config=None,
                       singleton_state={}, cwd=str(tmp_path / "elsewhere"))
    ret, tail = run_one_job(state, ["seed=1"], 7)
    assert ret.status == JobStatus.FAILED and ret.overrides == ["seed=1"] and tail == ""
    message = str(ret._return_value)
    assert message.startswith("job 7 failed on the Dask worker ") and "Traceback" in message
    assert "which this worker cannot see" in message


def test_finished_yields_jobs_as_they_end_and_stops_when_none_comes_back():
    """The launcher's wait (``stall_seconds``): each future as it finishes, failed ones
    too, then ``JobsStalled`` with the futures left when none finished in time (a job that
    hung, seen once in a test on a running cluster: the sweep waited until pytest's
    timeout)."""
    from distributed import Client

    from hydra_plugins.replication_dask_launcher.dask_launcher import JobsStalled, finished

    with Client(processes=False, n_workers=1, threads_per_worker=3,
                dashboard_address=":0") as client:
        slow = client.submit(time.sleep, 0.6, pure=False)
        fails = client.submit(int, "x", pure=False)
        quick = client.submit(time.sleep, 0.0, pure=False)
        futures = [slow, fails, quick]
        assert set(finished(futures, stall_seconds=None)) == set(futures)
        # (a thread cannot be stopped: the client's close waits for it, so not too long)
        hangs = client.submit(time.sleep, 1.5, pure=False)
        futures = [quick, hangs]
        seen = []
        with pytest.raises(JobsStalled) as stalled:
            for future in finished(futures, stall_seconds=0.3):
                seen.append(future)
        assert seen == [quick] and stalled.value.left == [hangs]


def test_dask_sweep_whose_jobs_stop_coming_back_ends_with_one_line(tmp_path, dask_cluster):
    """``hydra.launcher.stall_seconds``: a sweep whose jobs no longer come back ends with one
    error line and status 2 instead of waiting for ever. Here the limit is far below one
    job's time, so the first job counts as hung."""
    scheduler_file, _ = dask_cluster
    done = run_cli("-m", "experiment=cloth_identify", "method=paper_ea", "budget=50",
                   "seed=0", "hydra/launcher=dask", f"hydra.launcher.address={scheduler_file}",
                   "hydra.launcher.stall_seconds=0.05", f"hydra.sweep.dir={tmp_path / 'sweep'}")
    assert done.returncode == 2, done.stderr[-3000:]
    errors = [line for line in done.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and "no job of the sweep finished within hydra.launcher." \
        "stall_seconds=0.05 s; 1 of 1 job(s) still running or waiting (the first: " \
        "experiment=cloth_identify" in errors[0] and "resume=true" in errors[0], done.stderr
    assert "runs on until it ends" in errors[0] and "Traceback" not in done.stderr


@pytest.mark.parametrize("setting, message", [
    ("hydra.launcher.n_workers=0", "hydra.launcher.n_workers=0: expected an integer >= 1"),
    ("hydra.launcher.n_workers=abc", "hydra.launcher.n_workers='abc': expected an integer"),
    ("hydra.launcher.address=absent_scheduler.json", "no such scheduler file"),
    ("hydra.launcher.address=nonsense", "hydra.launcher.address=nonsense: not an address"),
    ("hydra.launcher.memory_limit=abc", "hydra.launcher.memory_limit='abc': not a size"),
    ("hydra.launcher.stall_seconds=0", "hydra.launcher.stall_seconds=0: expected a number "
     "of seconds > 0"),
    ("hydra.launcher.stall_seconds=abc", "hydra.launcher.stall_seconds='abc': expected"),
])
def test_dask_settings_it_cannot_use_are_one_error_line(tmp_path, setting, message):
    done = run_cli("-m", "experiment=fig08_mesh", "zoom=3,4", "hydra/launcher=dask",
                   f"hydra.sweep.dir={tmp_path / 'sweep'}",
                   f"figure_dir={tmp_path / 'f'}/" + "${zoom}", setting)
    assert done.returncode == 2 and done.stderr.startswith("error: ")
    assert message in done.stderr and "Traceback" not in done.stderr
    # refused before Hydra's sweeper writes anything: no multirun.yaml that replicate-gather
    # would read as the folder's last sweep
    assert not (tmp_path / "sweep").exists() and not (tmp_path / "f").exists()


def test_joblib_job_of_an_experiment_with_worker_processes_starts_them(tmp_path):
    """In a joblib (loky) worker the default start method is "loky", which the spawned
    processes of an experiment's own pool (cloth_baselines, workers: 2) could not find: every
    job ended in "cannot find context for 'loky'" tracebacks. They now start, and give the
    answers of a plain run. One job is enough: with n_jobs=2 joblib runs even a single job
    in a loky worker (only n_jobs=1 runs it in the launching process). One optimiser on the
    two references is two runs, enough for the experiment's pool of two processes. Each run
    is seeded alone, so the plain run, in one process, gives the answers the pool must."""
    study = ["experiment=cloth_baselines", "n_seeds=1", "budgets=[30]",
             "optimisers=[{name: GA, kind: pymoo, algorithm: ga, options: {pop_size: 10}}]",
             f"figure_dir={tmp_path / 'figures'}"]
    swept, plain, _ = swept_and_plain(tmp_path, study, ["seed=3"],
                                      ["hydra/launcher=joblib", "hydra.launcher.n_jobs=2"],
                                      plain_only=["workers=1"])

    def answers(path):
        runs = json.loads(path.read_text())["runs"]
        return {(case, name): [(r["curve"], r["at_budget"]) for r in rows]
                for case, by_name in runs.items() for name, rows in by_name.items()}
    assert answers(swept) == answers(plain)


def test_joblib_sweep_with_a_refused_job_runs_the_others_and_exits_2(tmp_path):
    """joblib used to stop the jobs running beside a refused one (and leave their staging
    folders); now every other job runs, and the sweep ends with one error line naming the
    refused job. Each job's result holds its own overrides (replicate-gather reads them)."""
    folder = tmp_path / "sweep"
    done = run_cli("-m", "experiment=cloth_identify", "method=paper_ea", "budget=50",
                   "seed=0,1", "data.path=README.md,synthetic_data/cloth/reference_tau0.5.npz",
                   "hydra/launcher=joblib", "hydra.launcher.n_jobs=2",
                   f"hydra.sweep.dir={folder}")
    assert done.returncode == 2, done.stderr[-3000:]
    summary = [line for line in done.stderr.splitlines()
               if line.startswith("error: ") and "job(s) of the sweep refused" in line]
    assert len(summary) == 1 and "README.md: cannot be read" in summary[0], done.stderr
    assert summary[0].startswith("error: 2 job(s)")
    assert "Traceback" not in done.stderr
    results = sorted(folder.rglob("result.json"))
    assert [p.parent.name.split(",")[-1] for p in results] == ["seed=0", "seed=1"]
    assert all("reference_tau0.5" in p.parent.name for p in results)
    overrides = json.loads(results[0].read_text())["overrides"]
    assert "seed=0" in overrides and "method=paper_ea" in overrides
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [p.parent.name for p in results] + ["multirun.yaml"])
