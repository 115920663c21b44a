"""Record how long the test suite took, for the speed summary in REPORT.md; no progress
bars or lines in tests unless a test asks for them (``REPLICATION_PROGRESS=none``)."""

import json
import os
import time
from pathlib import Path

from replication.machine import reference_seconds

os.environ.setdefault("REPLICATION_PROGRESS", "none")

_START = time.perf_counter()
ROOT = Path(__file__).resolve().parent.parent


def pytest_sessionfinish(session, exitstatus):
    """Write ``results/tests.json`` after a run of the whole suite (not a selection)."""
    if hasattr(session.config, "workerinput"):  # a pytest-xdist worker: the controller writes
        return
    options = session.config.option
    if (options.file_or_dir or options.keyword or options.markexpr or options.maxfail
            or options.collectonly):
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    counts = {key: len(reporter.stats.get(key, [])) for key in ("passed", "failed", "skipped",
                                                                 "error")}
    record = {"seconds": time.perf_counter() - _START, "exit_status": int(exitstatus),
              "collected": session.testscollected, **counts,
              "machine_reference_seconds": reference_seconds()}  # replication/machine.py
    path = ROOT / "results" / "tests.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(record, indent=1) + "\n")
