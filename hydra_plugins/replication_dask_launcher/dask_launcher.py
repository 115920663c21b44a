"""A Hydra launcher that runs the jobs of a sweep on a Dask cluster (``distributed``).

``replicate -m hydra/launcher=dask ...`` (``configs/hydra/launcher/dask.yaml``): each job of
the sweep becomes one Dask task that composes the job's config and runs it through Hydra's
``run_job`` in a worker process, as the basic launcher would in this one; the
``JobReturn`` objects come back in the order of the jobs.

``address: null`` starts a ``LocalCluster`` of ``n_workers`` processes on this machine for
the sweep and closes it after; ``address: tcp://HOST:8786`` (or a scheduler file) uses a
running cluster (``dask scheduler`` and ``dask worker``, docs/results.md). Workers must see
the same files at the same path as the machine that submits (a shared file system, the
repository as the working directory): job configs name relative paths
(``synthetic_data/...``, ``multirun/NAME``).

Hydra keeps its job state in process-wide singletons, so a worker process runs one job of
the sweep at a time, however many threads it has; scale with worker processes
(``dask worker ADDRESS --nworkers N --nthreads 1``).

The jobs done, their rate and the time left show as the suite's other long loops do
(``progress=`` in the config, :mod:`replication.progress`).

Hydra finds this class because it lives in the ``hydra_plugins`` namespace package; it
imports every module there at start-up, so ``distributed`` is imported only when a sweep
sets the launcher up (:meth:`DaskLauncher.setup`) or launches jobs.
"""

import contextlib
import io
import logging
import os
import sys
import threading
from pathlib import Path
from typing import Optional, Sequence, Tuple

from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, JobStatus, configure_log, run_job, setup_globals
from hydra.plugins.launcher import Launcher
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, OmegaConf, open_dict

# one job at a time per worker process (Hydra's HydraConfig and JobRuntime are singletons)
_ONE_JOB = threading.Lock()


class SweepState:
    """What every job of one sweep needs, sent to each worker once (a plain class: Hydra
    runs plugin modules before they are in ``sys.modules``, which dataclasses need)."""

    def __init__(self, hydra_context: HydraContext, task_function: TaskFunction,
                 config: DictConfig, singleton_state: dict, cwd: str,
                 environment: Optional[dict] = None) -> None:
        self.hydra_context = hydra_context
        self.task_function = task_function
        self.config = config
        self.singleton_state = singleton_state
        self.cwd = cwd
        # the sweep's variables for its jobs (replicate's REPLICATION_SWEEP: where a
        # refused job leaves its note): a worker started before the sweep, by hand or on
        # another machine, did not inherit them
        self.environment = dict(environment or {})


class TailedStream(io.TextIOBase):
    """A text stream that writes through to ``stream`` and keeps the last ``keep``
    characters written (``tail``)."""

    def __init__(self, stream, keep: int = 4000) -> None:
        super().__init__()
        self.stream = stream
        self.keep = keep
        self.tail = ""

    def write(self, text: str) -> int:
        self.stream.write(text)
        self.tail = (self.tail + text)[-self.keep:]
        return len(text)

    def flush(self) -> None:
        self.stream.flush()

    def isatty(self) -> bool:
        return self.stream.isatty()

    def fileno(self) -> int:
        return self.stream.fileno()


CONNECT_SECONDS = 10   # how long to wait for a remote scheduler


class JobsStalled(Exception):
    """No job of the sweep finished within the allowed time; ``left`` holds the futures
    still running or waiting."""

    def __init__(self, left):
        super().__init__(f"{len(left)} job(s) left")
        self.left = left


def finished(futures, stall_seconds=None):
    """Yield each of ``futures`` as it finishes (with a result, an error or cancelled),
    in the order they finish.

    Raises :class:`JobsStalled` when none of the futures still pending finishes within
    ``stall_seconds`` (``None``: wait for ever). While a worker runs jobs of the sweep, one
    of them finishes at the latest one job's duration after the last did, so a limit above
    the longest job's time only stops a sweep whose jobs no longer come back (a hung job,
    a worker that no longer answers).
    """
    from distributed import wait

    pending = set(futures)
    while pending:
        try:
            done, pending = wait(list(pending), timeout=stall_seconds,
                                 return_when="FIRST_COMPLETED")
        except TimeoutError:
            raise JobsStalled(sorted(pending, key=futures.index)) from None
        yield from sorted(done, key=futures.index)


def quiet_distributed_logs() -> None:
    """Keep ``distributed``'s own loggers to critical messages in this process. Run on each
    worker of the launcher's local cluster once its jobs are gathered: a worker's heartbeat
    in flight while the scheduler closes logs a ``CommClosedError`` traceback ("Failed to
    communicate with scheduler during heartbeat"), a race of the shutdown, not news."""
    logging.getLogger("distributed").setLevel(logging.CRITICAL)


def _refuse(message):
    """One ``error:`` line and exit status 2, as ``replication.cli._error`` writes (not
    called here: Hydra imports this module at start-up, before the suite's own)."""
    print(f"error: {message}", file=sys.stderr, flush=True)
    raise SystemExit(2)


def run_one_job(state: SweepState, overrides: Sequence[str],
                job_num: int) -> Tuple[JobReturn, str]:
    """:func:`run_job_here`, with anything it raises sent back as a failed job whose value is
    a ``RuntimeError`` holding the traceback as text (which always pickles: an exception
    Dask cannot serialise never reaches the client)."""
    import traceback

    try:
        return run_job_here(state, overrides, job_num)
    except Exception as error:
        text = "".join(traceback.format_exception(error))
        return JobReturn(overrides=list(overrides), status=JobStatus.FAILED,
                         _return_value=RuntimeError(
                             f"job {job_num} failed on the Dask worker "
                             f"{os.uname().nodename}: {text}")), ""


def run_job_here(state: SweepState, overrides: Sequence[str],
                 job_num: int) -> Tuple[JobReturn, str]:
    """Run one job of the sweep in this (worker) process.

    Returns its ``JobReturn`` and the last lines the job wrote on stderr (the worker's
    stderr, which the submitting machine does not see unless the cluster is local). A job
    that exits (``sys.exit``, as ``replicate`` does on a refused config) comes back as a
    failed ``JobReturn`` holding the ``SystemExit``, which Hydra's sweeper raises in the
    submitting process once every job is back.
    """
    with _ONE_JOB:
        if os.getcwd() != state.cwd:
            if not Path(state.cwd).is_dir():
                raise RuntimeError(
                    f"dask worker on {os.uname().nodename}: the sweep was submitted from "
                    f"{state.cwd}, which this worker cannot see; run the workers with the "
                    "repository at the same path (a shared file system)")
            os.chdir(state.cwd)  # every job of the sweep wants the same folder
        Singleton.set_state(state.singleton_state)
        setup_globals()
        config = state.hydra_context.config_loader.load_sweep_config(state.config,
                                                                     list(overrides))
        with open_dict(config.hydra.job) as job:
            job.id = f"dask_{job_num}"
            job.num = job_num
        stderr = TailedStream(sys.stderr)
        saved = {name: os.environ.get(name) for name in state.environment}
        os.environ.update(state.environment)
        try:
            with contextlib.redirect_stderr(stderr):
                ret = run_job(hydra_context=state.hydra_context,
                              task_function=state.task_function, config=config,
                              job_dir_key="hydra.sweep.dir", job_subdir_key="hydra.sweep.subdir")
        except SystemExit as exit_:
            status = JobStatus.COMPLETED if exit_.code in (0, None) else JobStatus.FAILED
            ret = JobReturn(overrides=list(overrides), status=status, _return_value=exit_)
        finally:
            for name, value in saved.items():   # the worker's own, for its next sweep
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value
        return sendable(ret, stderr.tail, job_num)


def sendable(ret: JobReturn, tail: str, job_num: int) -> Tuple[JobReturn, str]:
    """``(ret, tail)`` when Dask's pickling (``distributed.protocol.pickle.dumps``: pickle,
    else cloudpickle) takes it, as Dask must to send it back; else the job as failed with a
    ``RuntimeError`` that says what could not be sent and holds the job's own value as text
    (a traceback for an exception). A result Dask cannot serialise is logged in the worker
    ("Failed to serialize") but never reaches the client, whose sweep then waits for it for
    ever (CI once hung so after the workers had logged that line)."""
    import traceback

    from distributed.protocol.pickle import dumps

    result = (ret, tail)
    try:
        dumps(result)
        return result
    except Exception as error:
        value = ret._return_value
        text = ("".join(traceback.format_exception(value)) if isinstance(value, BaseException)
                else repr(value))
        failed = JobReturn(overrides=list(ret.overrides or []), status=JobStatus.FAILED,
                           _return_value=RuntimeError(
                               f"job {job_num}: its result cannot be sent back from the Dask "
                               f"worker ({type(error).__name__}: {error}); the job's value "
                               f"was: {text}"))
        return failed, tail


def close_quietly(client, cluster, reach_workers: bool = True) -> None:
    """Close ``client`` and, when the launcher started it, the local ``cluster``, without
    the shutdown's own log noise. Workers of a user's cluster are left as they are.

    Parameters
    ----------
    client, cluster
        What :meth:`DaskLauncher.connect` returned (``cluster`` is ``None`` for a user's).
    reach_workers
        Quiet the local workers' loggers first (a call to each worker); ``False`` after
        Ctrl-C, when the workers may already be going."""
    if cluster is None:
        client.close()
        return
    if reach_workers:
        with contextlib.suppress(Exception):  # a cluster already failing closes as it can
            client.run(quiet_distributed_logs)
    parent = logging.getLogger("distributed")
    level = parent.level
    parent.setLevel(logging.CRITICAL)  # the nannies and scheduler here, while they close
    try:
        client.close()
        cluster.close()
    finally:
        parent.setLevel(level)


class DaskLauncher(Launcher):
    """Hydra launcher: each job of a sweep is a task on a Dask cluster.

    Parameters
    ----------
    address : str or None
        Scheduler address (``tcp://HOST:8786``) or path of a scheduler file; ``None``
        starts a local cluster for the sweep.
    n_workers : int
        Worker processes of the local cluster (``address: null`` only).
    memory_limit : str or None
        Memory limit of each local worker (Dask's spelling, ``"4GiB"``; ``None``: Dask's
        default share of the machine's memory).
    stall_seconds : float or None
        Stop the sweep (one error line, status 2) when no job has finished for this long
        (:func:`finished`); ``None``: wait for ever. Set it above the longest job's time.
    """

    def __init__(self, address: Optional[str] = None, n_workers: int = 2,
                 memory_limit: Optional[str] = None,
                 stall_seconds: Optional[float] = None) -> None:
        self.address = address
        self.n_workers = n_workers   # checked when the sweep starts (one error line)
        self.memory_limit = memory_limit
        self.stall_seconds = stall_seconds
        self.config: Optional[DictConfig] = None
        self.task_function: Optional[TaskFunction] = None
        self.hydra_context: Optional[HydraContext] = None

    def setup(self, *, hydra_context: HydraContext, task_function: TaskFunction,
              config: DictConfig) -> None:
        self.config = config
        self.task_function = task_function
        self.hydra_context = hydra_context
        # settings it cannot use are refused here, before Hydra's sweeper writes the sweep
        # folder's multirun.yaml (which replicate-gather reads as the last sweep): a remote
        # scheduler must answer now; each launch (a sweeper may launch several batches)
        # connects again and closes its own client
        self._check_stall()
        if self.address:
            self._connect_remote().close()
        else:
            self._check_local()

    def _check_stall(self):
        """``stall_seconds``: null or a number > 0, or one error line."""
        value = self.stall_seconds
        if value is None:
            return
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not value > 0 or value == float("inf"):
            _refuse(f"hydra.launcher.stall_seconds={value!r}: expected a number of seconds "
                    "> 0 (stop the sweep when no job has finished for that long), or null "
                    "to wait for ever")

    def _connect_remote(self):
        """A ``distributed.Client`` on the configured scheduler, or one error line."""
        from distributed import Client

        address = str(self.address)
        if address.endswith(".json"):
            if not Path(address).is_file():
                _refuse(f"hydra.launcher.address={address}: no such scheduler file; "
                        "expected the file a scheduler wrote (dask scheduler "
                        "--scheduler-file FILE) or an address tcp://HOST:PORT")
            target = {"scheduler_file": address}
        else:
            target = {"address": address}
        try:
            return Client(**target, timeout=CONNECT_SECONDS)
        except ValueError as error:
            _refuse(f"hydra.launcher.address={address}: not an address ({error}); "
                    "expected tcp://HOST:PORT, a scheduler file (*.json), or null for "
                    "a local cluster")
        except (OSError, TimeoutError) as error:
            _refuse(f"hydra.launcher.address={address}: no Dask scheduler answered "
                    f"within {CONNECT_SECONDS} s ({type(error).__name__}: "
                    f"{str(error).splitlines()[0] if str(error) else ''}); expected a "
                    "running scheduler at tcp://HOST:PORT (or its scheduler file), or "
                    "address=null for a local cluster")

    def _check_local(self):
        """The local cluster's settings, or one error line."""
        if (isinstance(self.n_workers, bool) or not isinstance(self.n_workers, int)
                or self.n_workers < 1):
            _refuse(f"hydra.launcher.n_workers={self.n_workers!r}: expected an integer >= 1 "
                    "(worker processes of the local cluster)")
        if self.memory_limit is not None and str(self.memory_limit) != "auto":
            from dask.utils import parse_bytes

            try:
                parse_bytes(self.memory_limit)
            except (ValueError, TypeError):
                _refuse(f"hydra.launcher.memory_limit={self.memory_limit!r}: not a size; "
                        "expected Dask's spelling (4GiB, 500MB), auto or null")

    def connect(self):
        """``(client, cluster)``: a ``distributed.Client`` on the configured scheduler and
        ``None``, or on a new local cluster and that cluster (both closed after the
        batch of jobs)."""
        from distributed import Client, LocalCluster

        if self.address:
            return self._connect_remote(), None
        options = {} if self.memory_limit is None else {"memory_limit": self.memory_limit}
        # the scheduler's HTTP server on a free port: its default, 8787, is taken when
        # another cluster runs here (Dask then warns "Port 8787 is already in use")
        cluster = LocalCluster(n_workers=self.n_workers, threads_per_worker=1,
                               processes=True, host="127.0.0.1", dashboard_address=":0",
                               **options)
        return Client(cluster), cluster

    def launch(self, job_overrides: Sequence[Sequence[str]],
               initial_job_idx: int) -> Sequence[JobReturn]:
        assert self.config is not None and self.hydra_context is not None
        assert self.task_function is not None
        setup_globals()
        configure_log(self.config.hydra.hydra_logging, self.config.hydra.verbose)
        Path(str(self.config.hydra.sweep.dir)).mkdir(parents=True, exist_ok=True)
        from replication.cli import SWEEP_ENVIRONMENT

        environment = ({SWEEP_ENVIRONMENT: os.environ[SWEEP_ENVIRONMENT]}
                       if SWEEP_ENVIRONMENT in os.environ else {})
        state = SweepState(hydra_context=self.hydra_context, task_function=self.task_function,
                           config=self.config, singleton_state=Singleton.get_state(),
                           cwd=os.getcwd(), environment=environment)
        from concurrent.futures import CancelledError

        from distributed.scheduler import KilledWorker

        from replication.progress import bar, mode_for

        client, cluster = self.connect()
        interrupted = False
        try:
            print(f"dask launcher: {len(job_overrides)} jobs on {client.scheduler.address}",
                  file=sys.stderr, flush=True)
            shared = client.scatter(state, hash=False)
            futures = [client.submit(run_one_job, shared, list(overrides),
                                     initial_job_idx + offset, pure=False)
                       for offset, overrides in enumerate(job_overrides)]
            try:
                with mode_for(OmegaConf.select(self.config, "progress")), \
                        bar(len(futures), "sweep jobs") as jobs:
                    for _ in finished(futures, self.stall_seconds):
                        jobs.update()
                done = client.gather(futures)
            except JobsStalled as stalled:
                client.cancel(stalled.left, force=True)
                first = job_overrides[futures.index(stalled.left[0])]
                _refuse(f"no job of the sweep finished within hydra.launcher.stall_seconds="
                        f"{self.stall_seconds} s; {len(stalled.left)} of {len(futures)} "
                        f"job(s) still running or waiting (the first: "
                        f"{' '.join(first) or 'no overrides'}): a job hangs or needs longer "
                        "(raise stall_seconds, or null to wait for ever); the jobs that "
                        "finished kept their results, and resume=true re-runs only the "
                        "missing ones" + ("" if cluster is not None else
                                          "; a job still running on a worker of your "
                                          "cluster runs on until it ends or the worker "
                                          "is stopped"))
            except (CancelledError, KilledWorker) as error:
                _refuse(f"the Dask cluster lost a worker during the sweep ("
                        f"{type(error).__name__}): a job needed more memory than "
                        f"hydra.launcher.memory_limit={self.memory_limit} allows, or the "
                        "worker was stopped; raise the limit (or null), use fewer workers, "
                        "and resume=true re-runs only the missing jobs")
        except KeyboardInterrupt:
            # Ctrl-C: the local cluster's nannies log their workers' shutdown (warnings and
            # a CancelledError traceback) while it closes; the interruption is the news
            logging.getLogger("distributed").setLevel(logging.CRITICAL)
            interrupted = True
            raise
        finally:
            close_quietly(client, cluster, reach_workers=not interrupted)
        for ret, tail in done:
            if ret.status == JobStatus.FAILED and isinstance(ret._return_value, SystemExit):
                # Dask's transport keeps an exception's args but not SystemExit.code
                ret.return_value = SystemExit(*ret._return_value.args)
                if cluster is None:  # a remote worker's stderr: show why the job stopped
                    lines = tail.rstrip("\n").splitlines()[-10:]
                    print("\n".join(lines), file=sys.stderr, flush=True)
            elif cluster is None:
                # a job refused on a remote worker left its note for replicate's summary
                # line; its own error: line went to that worker's stderr: show it here
                refused = [line for line in tail.splitlines() if line.startswith("error: ")]
                if refused:
                    print(refused[-1], file=sys.stderr, flush=True)
        return [ret for ret, _ in done]

