"""Run one task per dataset of an outside study, serially or in worker processes.

Both blind studies on outside data (``discrepancy_outside`` and ``cloth_identify_outside``)
make each dataset in a temporary folder, analyse it and return one row; this runs those tasks
in the study's processes, reports each as it ends and keeps the rows in the order of the
specs (the answers do not depend on the number of processes: each task is seeded alone).
"""

from __future__ import annotations

import tempfile
from concurrent.futures import as_completed

from replication.workers import process_pool, usable_workers


def _in_own_folder(args):
    run, spec, payload = args
    with tempfile.TemporaryDirectory() as folder:
        return run(spec, payload, folder)


def run_datasets(run, specs, payload, *, workers, report):
    """``[run(spec, payload, folder) for spec in specs]``, in ``workers`` processes.

    Parameters
    ----------
    run : callable
        A module-level function (worker processes import it by name) of ``(spec, payload,
        folder)`` that writes only inside ``folder`` and returns the dataset's row.
    specs : list
    payload : object
        Passed to every call (settings, config); picklable.
    workers : int
        Processes; 1 (or a process that may not start any, such as a Dask worker: see
        :func:`replication.workers.usable_workers`) runs the tasks here, one after another.
    report : callable
        ``report(done, total, row)`` as each task ends (``done`` counts from 0).

    Returns
    -------
    list
        The rows, in the order of ``specs``.
    """
    rows = [None] * len(specs)
    if usable_workers(workers, "datasets") == 1:
        with tempfile.TemporaryDirectory() as folder:
            for index, spec in enumerate(specs):
                rows[index] = run(spec, payload, folder)
                report(index, len(specs), rows[index])
        return rows
    with process_pool(workers) as pool:
        futures = {pool.submit(_in_own_folder, (run, spec, payload)): index
                   for index, spec in enumerate(specs)}
        for done, future in enumerate(as_completed(futures)):
            index = futures[future]
            rows[index] = future.result()
            report(done, len(specs), rows[index])
    return rows
