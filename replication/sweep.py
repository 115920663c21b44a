"""``replicate-gather``: gather the ``result.json`` files of a sweep into one tidy CSV.

One row per run: the run folder, the experiment, the seed, the sweep's overrides (from the
folder name that Hydra's ``override_dirname`` gives) and every numeric leaf of the result
outside ``config`` and ``versions``, flattened with dots (``metrics.spring_updates...``).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

SKIP = {"config", "versions", "provenance"}


def flatten(value, prefix=""):
    """Numeric and string leaves of nested dicts and lists, keys joined with dots."""
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = ((str(i), v) for i, v in enumerate(value))
    else:
        return {prefix: value} if isinstance(value, (int, float, str, bool)) else {}
    flat = {}
    for key, item in items:
        flat.update(flatten(item, f"{prefix}.{key}" if prefix else str(key)))
    return flat


def overrides_of(run_dir):
    """``key=value`` pairs from a Hydra ``override_dirname`` folder name."""
    pairs = {}
    for part in run_dir.name.split(","):
        key, sep, value = part.partition("=")
        if sep:
            pairs[f"override.{key}"] = value
    return pairs


def gather(sweep_dir):
    """Rows (dicts) for every ``result.json`` below ``sweep_dir``, sorted by folder."""
    rows = []
    for path in sorted(Path(sweep_dir).rglob("result.json")):
        result = json.loads(path.read_text())
        row = {"run": str(path.parent.relative_to(sweep_dir)), **overrides_of(path.parent)}
        row.update(flatten({k: v for k, v in result.items() if k not in SKIP}))
        rows.append(row)
    return rows


def main(argv=None):
    """Write the tidy CSV of a sweep folder (default: SWEEP_DIR/results.csv)."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("sweep_dir")
    parser.add_argument("--output", default=None)
    args = parser.parse_args(argv)
    sweep_dir = Path(args.sweep_dir)
    if not sweep_dir.is_dir():
        print(f"error: {sweep_dir}: no such folder", file=sys.stderr)
        return 2
    rows = gather(sweep_dir)
    if not rows:
        print(f"error: {sweep_dir}: no result.json below it", file=sys.stderr)
        return 2
    columns = sorted({key for row in rows for key in row},
                     key=lambda k: (k not in ("run", "experiment", "seed"), k))
    output = Path(args.output) if args.output else sweep_dir / "results.csv"
    with open(output, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {output} ({len(rows)} runs, {len(columns)} columns)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
