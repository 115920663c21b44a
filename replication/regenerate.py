"""``replicate-all``: regenerate every figure, table and REPORT.md.

Runs each experiment that has a ``report`` block, in report order, through the real
command line (``replicate experiment=NAME``). A result is recomputed only when its
experiment config, the main config, the package code or an experiment it depends on
(``report.depends_on``) changed since it was made; ``--force`` recomputes everything.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from replication.provenance import PROJECT_ROOT, code_hash
from replication.report import CONFIG_DIR, build_report, experiment_entries

CACHE_FILE = ".regenerate-cache.json"


def experiment_keys(entries, config_dir=CONFIG_DIR):
    """Cache key per experiment: its config, the main config, the code, its dependencies."""
    base = hashlib.sha256()
    base.update(code_hash().encode())
    base.update((Path(config_dir).parent / "config.yaml").read_bytes())
    keys = {}
    for _, name, block in entries:
        digest = hashlib.sha256(base.digest())
        digest.update((Path(config_dir) / f"{name}.yaml").read_bytes())
        for dependency in block.get("depends_on", []):
            digest.update(keys.get(dependency, dependency).encode())
        keys[name] = digest.hexdigest()
    return keys


def main(argv=None):
    """Regenerate results (cached), figures and REPORT.md."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--force", action="store_true", help="recompute every result")
    parser.add_argument("--only", default="", help="comma-separated experiment names")
    parser.add_argument("--results", default="results")
    args = parser.parse_args(argv)

    results = Path(args.results)
    results.mkdir(parents=True, exist_ok=True)
    cache_path = results / CACHE_FILE
    cache = json.loads(cache_path.read_text()) if cache_path.exists() else {}
    entries = experiment_entries()
    keys = experiment_keys(entries)
    only = {name for name in args.only.split(",") if name}
    unknown = only - set(keys)
    if unknown:
        print(f"error: --only: unknown experiment(s) {sorted(unknown)}; known: {sorted(keys)}",
              file=sys.stderr)
        return 2
    failures = []
    timings = {}
    start = time.perf_counter()
    gathered = [name for _, name, block in entries if block.get("gather")]
    for index, (_, name, _) in enumerate(entries, 1):
        if (only and name not in only) or name in gathered:
            continue
        done = (results / name / "result.json").exists() and cache.get(name) == keys[name]
        label = f"[{index}/{len(entries)}] {name}"
        if done and not args.force:
            print(f"{label}: up to date", flush=True)
            timings[name] = "up to date"
            continue
        print(f"{label}: running", flush=True)
        t0 = time.perf_counter()
        command = [sys.executable, "-m", "replication.cli", f"experiment={name}",
                   f"out={results / name}"]
        status = subprocess.run(command, cwd=PROJECT_ROOT, check=False).returncode
        if status != 0:
            failures.append(name)
            cache.pop(name, None)
            print(f"{label}: FAILED (exit {status})", flush=True)
        else:
            cache[name] = keys[name]
            timings[name] = time.perf_counter() - t0
            print(f"{label}: done in {timings[name]:.1f} s", flush=True)
        cache_path.write_text(json.dumps(cache, indent=1, sort_keys=True))
    record = {"total_seconds": time.perf_counter() - start, "experiments": timings,
              "cpu_count": os.cpu_count(),
              "forced": args.force, "only": sorted(only), "failures": failures}
    (results / "regenerate.json").write_text(json.dumps(record, indent=1) + "\n")
    if not only and not failures and "up to date" not in timings.values():
        (results / "regenerate-full.json").write_text(json.dumps(record, indent=1) + "\n")
    for name in gathered:  # gatherers read the records above, so they run last, always
        command = [sys.executable, "-m", "replication.cli", f"experiment={name}",
                   f"out={results / name}"]
        if subprocess.run(command, cwd=PROJECT_ROOT, check=False).returncode != 0:
            failures.append(name)
    report_path = PROJECT_ROOT / "REPORT.md"
    report_path.write_text(build_report(results))
    print(f"wrote {report_path} ({time.perf_counter() - start:.1f} s in all)")
    if failures:
        print(f"error: {len(failures)} experiment(s) failed: {', '.join(failures)}",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
