"""Processes that share the CPUs: worker pools, and the experiments ``replicate-all`` runs
side by side.

Each of ``n`` processes gets ``cpus // n`` numba, OpenMP and BLAS threads (at least one),
and idle OpenMP threads sleep. Without that, processes on two cores each start two
threads that busy-wait for one another (OpenBLAS ignores the OpenMP policy): one
``discrepancy_blind`` dataset took 6.6 s of CPU alone with the default threads, 29.6 s
beside two busy processes, and 5.1 s there with one thread of each kind. Values the user
set are kept.

numba's thread count changes no result (its parallel loops run independent jobs, each
summed in order); OpenBLAS's does, at round-off: the discrepancy studies moved by up to
2.3e-7 relative between two and one BLAS threads, more where residuals are round-off.
``discrepancy_outside`` had a forked pool of its own, with each library's default threads:
4 datasets of 200-300 frames took 113 s (63 s of CPU) beside other busy runs, and 28 s
(11 s of CPU) in this module's pool, with the same answers to the last digit.

A daemonic process may not start processes (``multiprocessing`` refuses: "daemonic
processes are not allowed to have children"): a Dask worker runs its tasks in one, so an
experiment with ``workers: 2`` swept through ``hydra/launcher=dask`` ran into that
traceback. :func:`usable_workers` makes such a process run its tasks itself.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
from concurrent.futures import ProcessPoolExecutor

THREAD_VARIABLES = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                    "MKL_NUM_THREADS")


def shared_threads(environ, shares, cpus=None):
    """``environ`` with ``cpus // shares`` threads (at least 1) for each threaded library,
    and idle OpenMP threads asleep, unless the variable is already set; unchanged for one
    process (``replicate-all`` gives benchmarks, which run alone, the defaults).

    Parameters
    ----------
    environ : mapping
        The environment to start from (not changed).
    shares : int
        Processes that will run at once.
    cpus : int, optional
        CPUs to share (default ``os.cpu_count()``).
    """
    environ = dict(environ)
    if shares > 1:
        cpus = (os.cpu_count() or 1) if cpus is None else cpus
        threads = str(max(1, cpus // shares))
        environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
        for name in THREAD_VARIABLES:
            environ.setdefault(name, threads)
    return environ


def usable_workers(workers, what="tasks"):
    """``workers``, or 1 in a daemonic process (a Dask worker, a pool's worker), which may
    not start processes of its own; it then says so (a ``note:`` line on stderr, once per
    process) and runs its ``what`` itself, one after another. Results do not depend on the
    number of workers (up to BLAS round-off: see above).

    Parameters
    ----------
    workers : int
        Processes the experiment asks for.
    what : str
        What the tasks are, for the message.
    """
    global _SAID_DAEMON
    workers = int(workers)
    if workers > 1 and multiprocessing.current_process().daemon:
        if not _SAID_DAEMON:   # once: a study runs its experiment many times
            print(f"note: {what}: this process is a daemon (a Dask worker, say) and may not "
                  f"start processes; it runs its tasks itself, one at a time, not in "
                  f"{workers} processes (same answers, up to BLAS round-off)",
                  file=sys.stderr, flush=True)
            _SAID_DAEMON = True
        return 1
    return workers


_SAID_DAEMON = False


_KEPT = None  # while kept_pools() is open: (its ExitStack, {(workers, initializer): pool})


@contextlib.contextmanager
def kept_pools():
    """Within this block, :func:`process_pool` hands out one pool per ``(workers,
    initializer)`` and closes it only when the block ends. For studies that run an
    experiment many times (a spawned worker costs about 2 s of CPU to start: imports and
    compiled kernels); use it only where tasks depend on nothing a worker keeps between
    them. Nested blocks use the outer one's pools. The thread variables of the first pool
    stay set in this process's environment until the block ends."""
    global _KEPT
    if _KEPT is not None:
        yield
        return
    try:
        with contextlib.ExitStack() as stack:
            _KEPT = (stack, {})
            yield
    finally:
        _KEPT = None


@contextlib.contextmanager
def process_pool(workers, initializer=None):
    """A :class:`ProcessPoolExecutor` of ``workers`` spawned processes that share the CPUs
    (see the module docstring); inside :func:`kept_pools`, the pool kept for ``(workers,
    initializer)``.

    Parameters
    ----------
    workers : int
    initializer : callable, optional
        Run once in each worker.
    """
    if _KEPT is not None:
        stack, pools = _KEPT
        key = (workers, initializer)
        if key not in pools:
            pools[key] = stack.enter_context(_new_pool(workers, initializer))
        yield pools[key]
        return
    with _new_pool(workers, initializer) as pool:
        yield pool


@contextlib.contextmanager
def _new_pool(workers, initializer):
    saved = dict(os.environ)
    # a spawned worker sets the start method its parent's default context names; in a
    # joblib (loky) worker that is "loky", which a plain spawned process cannot find
    # ("cannot find context for 'loky'"): the pool's workers are told "spawn" instead
    method = multiprocessing.get_start_method(allow_none=True)
    foreign = method is not None and method not in multiprocessing.get_all_start_methods()
    try:
        if foreign:
            multiprocessing.set_start_method("spawn", force=True)
        # workers start when tasks arrive and read the environment then: it stays set (only
        # for this process's children: its own libraries started long ago) until the pool
        # ends
        os.environ.update(shared_threads(os.environ, workers))
        context = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                   initializer=initializer)
        try:
            yield pool
        except BaseException:
            # an error or Ctrl-C: the queued tasks are dropped, not run before it surfaces
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    finally:
        os.environ.clear()
        os.environ.update(saved)
        if foreign:
            multiprocessing.set_start_method(method, force=True)
