"""``replicate-gather``: gather the ``result.json`` files of a sweep into one tidy CSV and plots.

One row per run: the run folder, the experiment, the seed, the sweep's overrides (from the
result's ``overrides`` list, the job's overrides as Hydra passed them; results without one
give them from the folder name that Hydra's ``override_dirname`` gives) and every numeric
leaf of the result outside ``config``, ``versions`` and ``overrides``, flattened with dots
(``metrics.spring_updates...``), with the run's ``provenance``
(``provenance.config_sha256``, ``provenance.code_sha256``,
``provenance.inputs_sha256.PATH``; one ``provenance.inputs_sha256`` column of
``PATH:SHA256;...`` when the runs read different files), so that a committed CSV can be
checked for staleness. Result folders below a hidden folder (a run's ``.NAME.partial-*``
staging folder) are not runs.

Plots: one PNG per metric in the sweep folder, the metric against one swept override (the
x axis, numeric when its values are numbers), one line per combination of the other
varying overrides; each run is a point, the line joins the medians over seeds (runs that
differ only in ``seed``). The metrics are ``--metric COLUMN`` or else the experiment
config's ``sweep_metrics:`` list.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import re
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np

from replication.interrupts import interruptible

SKIP = {"config", "versions", "overrides"}
PREFIX = "override."
SEED = PREFIX + "seed"
INPUTS = "provenance.inputs_sha256"


class SweepError(Exception):
    """A metric or override name that the gathered results do not have."""


def flatten(value, prefix=""):
    """Numeric and string leaves of nested dicts and lists, keys joined with dots.

    Parameters
    ----------
    value : dict, list or scalar
    prefix : str
        Key of ``value`` itself (``""`` at the top).
    """
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


@lru_cache(maxsize=1)
def _parser():
    from hydra.core.override_parser.overrides_parser import OverridesParser

    return OverridesParser.create()


def parse_override(text):
    """``(key, key_or_group, value)`` of one override string, as Hydra reads it.

    ``key`` keeps the ``+``, ``++`` or ``~`` prefix (as the run-folder name shows it);
    ``value`` is a quoted or plain string without its quotes and escapes, otherwise the
    text after ``=`` as Hydra writes it (numbers, ``null``, lists: ``[150,200]``), ``""``
    for a deletion without a value. A string Hydra cannot parse is split at its first ``=``.

    Parameters
    ----------
    text : str
        ``key=value``, e.g. ``+cost.frames=[150,200]`` or ``data.path='/a b/c,1.npz'``.
    """
    from hydra.errors import HydraException

    raw_key, _, raw_value = text.partition("=")
    try:
        override = _parser().parse_override(text)
    except HydraException:
        return raw_key.strip(), raw_key.strip().lstrip("+~"), raw_value.strip()
    value = override.value()
    return (override.get_key_element(), override.key_or_group,
            value if isinstance(value, str) else raw_value.strip())


def split_outside_brackets(text, sep=","):
    """``text`` split at each ``sep`` that is not inside brackets or quotes nor escaped
    (``\\,``, as Hydra writes a comma in a plain string); at every ``sep`` when the
    brackets or quotes do not pair up.

    Parameters
    ----------
    text : str
    sep : str
        One character.
    """
    items, depth, quote, start = [], 0, None, 0
    for i, char in enumerate(text):
        if quote:
            if char == quote and text[i - 1] != "\\":
                quote = None
        elif char in "'\"":
            quote = char
        elif char in "[{(":
            depth += 1
        elif char in "]})":
            depth -= 1
            if depth < 0:
                return text.split(sep)
        elif char == sep and depth == 0 and text[i - 1:i] != "\\":
            items.append(text[start:i])
            start = i + 1
    if quote or depth:
        return text.split(sep)
    return items + [text[start:]]


def overrides_of(run_dir):
    """``{override.KEY: value}`` from a Hydra ``override_dirname`` folder name.

    ``run_dir`` is relative to the sweep folder. The suite writes a ``/`` in a value as
    ``%2F`` (and ``%`` as ``%25``: ``replication.cli.folder_name``), decoded here; sweeps
    made before that nested the folder at a ``/``, so the whole path is read. Items are
    split at commas outside brackets and quotes (``+cost.frames=[150,200],seed=0``); values
    as :func:`parse_override` gives them. A value holding a comma outside brackets and
    quotes cannot be told from two items: :func:`run_overrides` reads the result's own
    list when it has one.

    Parameters
    ----------
    run_dir : str or Path
    """
    pairs = {}
    for item in split_outside_brackets(Path(run_dir).as_posix()):
        item = item.replace("%2F", "/").replace("%25", "%")
        if "=" in item or item.startswith("~"):
            key, _, value = parse_override(item)
            pairs[f"{PREFIX}{key}"] = value
    return pairs


def run_overrides(run_dir, result, exclude_keys=()):
    """``{override.KEY: value}`` of one run: from the result's ``overrides`` (the job's
    overrides as Hydra passed them, after the sweep's expansion) without the keys Hydra
    leaves out of folder names, or else from the folder name (:func:`overrides_of`).

    Parameters
    ----------
    run_dir : str or Path
        The run folder, relative to the sweep folder.
    result : dict
        The run's ``result.json``.
    exclude_keys : collection of str
        ``hydra.job.config.override_dirname.exclude_keys`` (:func:`excluded_keys`).
    """
    task = result.get("overrides")
    if not (isinstance(task, list) and all(isinstance(item, str) for item in task)):
        return overrides_of(run_dir)
    pairs = {}
    for item in task:
        key, key_or_group, value = parse_override(item)
        if key_or_group not in exclude_keys:
            pairs[f"{PREFIX}{key}"] = value
    return pairs


def excluded_keys(sweep_dir):
    """The keys Hydra leaves out of the run-folder names: those of the sweep's
    ``multirun.yaml``, else of ``configs/config.yaml``.

    Parameters
    ----------
    sweep_dir : str or Path
    """
    from omegaconf import OmegaConf

    from replication.cli import CONFIG_DIR

    for path in (Path(sweep_dir) / "multirun.yaml", Path(CONFIG_DIR) / "config.yaml"):
        try:
            keys = OmegaConf.select(OmegaConf.load(path),
                                    "hydra.job.config.override_dirname.exclude_keys")
        except Exception:  # noqa: BLE001  (no such file, not YAML: try the next)
            continue
        if keys is not None:
            return {str(key) for key in keys}
    return set()


def load_results(sweep_dir):
    """``(run folder relative to sweep_dir, result dict)`` for every ``result.json`` below
    ``sweep_dir``, sorted by folder; none below a hidden folder (a run's staging folder
    ``.NAME.partial-*``, left by a run killed while writing its result, ``.submitit``).

    Parameters
    ----------
    sweep_dir : str or Path
    """
    from replication.results import read_result

    paths = sorted(Path(sweep_dir).rglob("result.json"))
    return [(path.parent.relative_to(sweep_dir), read_result(path)) for path in paths
            if not any(part.startswith(".") for part in path.relative_to(sweep_dir).parts)]


def check_one_experiment(results):
    """Refuse results of more than one experiment (one CSV would mix their columns)."""
    names = {}
    for run, result in results:
        names.setdefault(str(result.get("experiment")), str(run))
    if len(names) > 1:
        pairs = ", ".join(f"{name} ({run or '.'})" for name, run in sorted(names.items()))
        raise SweepError(f"results of {len(names)} experiments below the folder: {pairs}; "
                         "expected one sweep of one experiment")


SUITE_SUBDIR = "${folder_name:${hydra.job.override_dirname}}"  # configs/config.yaml


def expected_runs(sweep_dir):
    """The run folders (relative names) the last sweep into ``sweep_dir`` made, from its
    ``multirun.yaml`` (Hydra's basic sweeper: every combination of the swept values), or
    ``None`` when that cannot be told (no ``multirun.yaml``, another sweeper, another
    ``hydra.sweep.subdir`` than the suite's)."""
    from hydra._internal.config_loader_impl import get_overrides_dirname
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf

    from replication.cli import folder_name

    path = Path(sweep_dir) / "multirun.yaml"
    if not path.is_file():
        return None
    try:
        hydra = OmegaConf.load(path).hydra
        subdir = OmegaConf.to_container(hydra.sweep, resolve=False)["subdir"]
        if (not str(hydra.sweeper._target_).endswith("BasicSweeper")
                or subdir != SUITE_SUBDIR):
            return None
        dirname = hydra.job.config.override_dirname
        parser = OverridesParser.create()
        batches = BasicSweeper.split_arguments(
            parser.parse_overrides(list(hydra.overrides.task)), None)
        return {folder_name(get_overrides_dirname(parser.parse_overrides(job),
                                                  list(dirname.exclude_keys),
                                                  dirname.item_sep, dirname.kv_sep))
                for batch in batches for job in batch}
    except Exception:  # noqa: BLE001  (a check only: no check rather than a failure)
        return None


def sweep_warnings(sweep_dir, runs):
    """Lines on the runs of ``sweep_dir`` that do not match its last sweep: jobs without a
    result (a sweep cut short) and results the last sweep did not make (an earlier sweep
    into the same folder, gathered with it).

    Parameters
    ----------
    sweep_dir : str or Path
    runs : list of str or Path
        The run folders found, relative to ``sweep_dir``.
    """
    expected = expected_runs(sweep_dir)
    if expected is None:
        return []
    # the run folders' names are written already (a '/' in a value as %2F); a sweep made
    # before that nested its folders at each '/': the same names
    found = {"%2F".join(Path(run).parts) for run in runs}
    lines = []
    missing = sorted(expected - found)
    if missing:
        lines.append(f"warning: {len(missing)} of the {len(expected)} jobs of the last sweep "
                     f"(multirun.yaml) have no result.json, e.g. {missing[0]}: the CSV "
                     "leaves them out (a sweep cut short or a refused job; the same command "
                     "with resume=true runs only those)")
    extra = sorted(found - expected)
    if extra:
        lines.append(f"warning: {len(extra)} result(s) below {sweep_dir} were not made by "
                     f"its last sweep (multirun.yaml), e.g. {extra[0]}: an earlier sweep "
                     "into the same folder; the CSV holds both (as a study of several "
                     "sweeps wants; hydra.sweep.dir=DIR keeps sweeps apart)")
    return lines


def gather(sweep_dir, results=None):
    """Rows (dicts) for every ``result.json`` below ``sweep_dir`` (or for ``results``, as
    :func:`load_results` gives them), sorted by folder.

    Parameters
    ----------
    sweep_dir : str or Path
        A multirun folder (``multirun/NAME``).
    results : list, optional
        ``(run folder, result)`` pairs already loaded.
    """
    exclude = excluded_keys(sweep_dir)
    rows = []
    for run, result in load_results(sweep_dir) if results is None else results:
        row = {"run": str(run), **run_overrides(run, result, exclude)}
        row.update(flatten({k: v for k, v in result.items() if k not in SKIP}))
        rows.append(row)
    return one_inputs_column(rows)


def one_inputs_column(rows):
    """``rows`` with their ``provenance.inputs_sha256.PATH`` columns as one column
    ``provenance.inputs_sha256`` (``PATH:SHA256`` of each file, sorted, joined by ``;``)
    when the runs do not all read the same files (a sweep over ``data.path``: one mostly
    empty column per file otherwise); unchanged when they do. :func:`inputs_of` reads
    both forms back.

    Parameters
    ----------
    rows : list of dict
        Rows of :func:`gather`, changed in place.
    """
    head = INPUTS + "."
    if len({frozenset(key for key in row if key.startswith(head)) for row in rows}) <= 1:
        return rows
    for row in rows:
        pairs = sorted((key[len(head):], row.pop(key))
                       for key in [key for key in row if key.startswith(head)])
        row[INPUTS] = ";".join(f"{path}:{sha}" for path, sha in pairs)
    return rows


def inputs_of(line):
    """``{path: sha256}`` of the input files of a gathered line, from either form of
    :func:`one_inputs_column`.

    Parameters
    ----------
    line : dict
        A row of :func:`gather` or of :func:`read_gathered`.
    """
    head = INPUTS + "."
    pairs = {key[len(head):]: value for key, value in line.items()
             if key.startswith(head) and value not in (None, "")}
    pairs.update(re.findall(r"(.+?):([0-9a-f]{64})(?:;|$)", line.get(INPUTS) or ""))
    return pairs


def cell_value(text):
    """A cell of a gathered CSV back as a number, bool, ``None`` (empty) or string.

    Parameters
    ----------
    text : str or None
    """
    if text in ("", None):
        return None
    if text in ("True", "False"):
        return text == "True"
    try:
        number = float(text)
    except ValueError:
        return text
    return int(number) if number.is_integer() and math.isfinite(number) else number


def read_gathered(path):
    """The rows of a gathered CSV (as :func:`main` writes it) as dicts of typed cells
    (:func:`cell_value`); ``[]`` when the file does not exist.

    Parameters
    ----------
    path : str or Path
    """
    path = Path(path)
    if not path.is_file():
        return []
    with open(path, newline="") as handle:
        return [{key: cell_value(value) for key, value in line.items()}
                for line in csv.DictReader(handle)]


def configured_metrics(results):
    """The ``sweep_metrics`` of the runs' resolved configs (``results`` as
    :func:`load_results` gives them), in order, without repeats."""
    metrics = []
    for _, result in results:
        for name in (result.get("config") or {}).get("sweep_metrics") or []:
            if name not in metrics:
                metrics.append(str(name))
    return metrics


def _number(value):
    """``value`` as a finite float, or ``None`` (strings, booleans, NaN, inf, missing)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def numeric_columns(rows):
    """Result columns holding numbers in every run that has them, those that vary first."""
    columns = {key for row in rows for key in row if not key.startswith(PREFIX)}
    numeric = [key for key in columns if key not in ("seed", "run")
               and all(isinstance(row[key], (int, float)) and not isinstance(row[key], bool)
                       for row in rows if key in row)]
    varies = {key: len({row.get(key) for row in rows}) > 1 for key in numeric}
    return sorted(numeric, key=lambda key: (not varies[key], key))


def varying_overrides(rows):
    """Override columns whose value is not the same in every run, sorted."""
    keys = sorted({key for row in rows for key in row if key.startswith(PREFIX)})
    return [key for key in keys if len({row.get(key) for row in rows}) > 1]


def check_names(rows, metrics, x):
    """Refuse metrics that are not numeric columns and an ``x`` that is not an override.

    Returns the x column (``override.NAME``) or ``None`` when nothing varies.

    Parameters
    ----------
    rows : list of dict
        Rows of :func:`gather`.
    metrics : list of str
        Column names asked for (``--metric``).
    x : str or None
        The override asked for as x axis (``--x``), or ``None`` for the first by name of
        those that vary (``seed`` last).
    """
    numeric = numeric_columns(rows)
    for metric in metrics:
        if metric not in numeric:
            what = "not a numeric column" if any(metric in row for row in rows) else \
                "not a column"
            raise SweepError(f"metric {metric!r}: {what} of the gathered results; expected "
                             f"one of {_few(numeric)}")
    overrides = sorted({key for row in rows for key in row if key.startswith(PREFIX)})
    if x is None:
        varying = varying_overrides(rows)
        others = [key for key in varying if key != SEED]
        return (others or varying or [None])[0]
    column = x if x.startswith(PREFIX) else PREFIX + x
    if column not in overrides:
        names = ", ".join(key[len(PREFIX):] for key in overrides) or "none"
        raise SweepError(f"--x {x}: not an override of this sweep; overrides: {names}")
    return column


def _few(names, n=6):
    return ", ".join(names[:n]) + (", ..." if len(names) > n else "") if names else "none"


def median_by_x(pairs):
    """Median of the y values at each x: ``[(x, y), ...] -> [(x, median), ...]`` sorted by x."""
    by_x = {}
    for xv, yv in pairs:
        by_x.setdefault(xv, []).append(yv)
    return [(xv, float(np.median(by_x[xv]))) for xv in sorted(by_x)]


def series(rows, metric, x):
    """The lines of one plot: ``metric`` against the override column ``x``.

    Runs are grouped by the other varying overrides except ``seed``; within a group the
    line is the median over the runs at each x (runs differing only in seed).

    Parameters
    ----------
    rows : list of dict
    metric : str
        A numeric column.
    x : str
        An override column (``override.NAME``).

    Returns
    -------
    numeric : bool
        Whether every x value is a number (then x values are floats, else strings).
    lines : list of dict
        ``{"label", "points": [(x, y)], "median": [(x, median)]}``, sorted by the other
        overrides' values (numbers by value);
        runs without a finite value of ``metric`` are left out.
    """
    values = [row.get(x) for row in rows]
    numeric = all(_is_float(v) for v in values)
    others = [key for key in varying_overrides(rows) if key not in (x, SEED)]
    groups = {}
    for row in rows:
        y = _number(row.get(metric))
        if y is None:
            continue
        xv = float(row[x]) if numeric else str(row.get(x))
        group = tuple(row.get(key) for key in others)
        groups.setdefault(group, []).append((xv, y))
    lines = [{"label": ", ".join(f"{key[len(PREFIX):]}={value}"
                                 for key, value in zip(others, group)),
              "points": sorted(pairs), "median": median_by_x(pairs)}
             for group, pairs in sorted(groups.items(), key=lambda item: _order(item[0]))]
    return numeric, lines


def _order(values):
    """Sort key of override values: numbers by value, before strings."""
    return tuple((0, float(v), "") if _is_float(v) else (1, 0.0, str(v)) for v in values)


def _is_float(value):
    try:
        return math.isfinite(float(value))
    except (TypeError, ValueError):
        return False


def plot_name(metric, x):
    """File name of the plot of ``metric`` against the override column ``x``.

    Parameters
    ----------
    metric : str
    x : str
    """
    safe = lambda name: re.sub(r"[^A-Za-z0-9._-]+", "_", name)  # noqa: E731
    return f"sweep_{safe(metric)}_vs_{safe(x[len(PREFIX):])}.png"


def write_plots(rows, metrics, x, folder):
    """One PNG per metric in ``folder``; returns the paths.

    Parameters
    ----------
    rows : list of dict
    metrics : list of str
    x : str
        The override column of the x axis.
    folder : Path
    """
    from replication.figures.sweep import plot_series

    paths = []
    for metric in metrics:
        numeric, lines = series(rows, metric, x)
        paths.append(plot_series(lines, numeric=numeric, metric=metric,
                                 x_label=x[len(PREFIX):], path=Path(folder) / plot_name(metric, x)))
    return paths


def main(argv=None):
    """Write the tidy CSV of a sweep folder (default: SWEEP_DIR/results.csv) and its plots."""
    try:
        with interruptible():  # a Ctrl-C that lands in an import is not lost
            return _main(argv)
    except OSError as error:
        where = f"{error.filename}: " if error.filename else ""
        print(f"error: {where}{error.strerror or error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130


def _main(argv=None):
    parser = argparse.ArgumentParser(prog="replicate-gather", description=main.__doc__)
    parser.add_argument("sweep_dir")
    parser.add_argument("--output", default=None)
    parser.add_argument("--metric", action="append", default=None, metavar="COLUMN",
                        help="a numeric column to plot (repeatable); default: the "
                             "experiment config's sweep_metrics")
    parser.add_argument("--x", default=None, metavar="OVERRIDE",
                        help="the swept override on the x axis; default: the first one "
                             "that varies, other than seed")
    parser.add_argument("--no-plots", action="store_true",
                        help="write the CSV only")
    from replication.errors import one_line_error

    parser.error = one_line_error
    args = parser.parse_args(argv)
    sweep_dir = Path(args.sweep_dir)
    if not sweep_dir.is_dir():
        found = "is a file" if sweep_dir.exists() else "no such folder"
        print(f"error: {sweep_dir}: {found}; expected a sweep folder (multirun/NAME, "
              "with one result.json per run below it)", file=sys.stderr)
        return 2
    if (sweep_dir / "result.json").is_file():
        print(f"error: {sweep_dir}: a single run's folder (its result.json is in it, not "
              "below it); expected a sweep folder (multirun/NAME, with one result.json per "
              "run below it)", file=sys.stderr)
        return 2
    output = Path(args.output) if args.output else sweep_dir / "results.csv"
    if output.name == "result.json":
        what = ("a run's result (not overwritten)" if output.exists() else
                "named as a run's result (a later gather would read it as one)")
        print(f"error: --output {output}: {what}; expected a CSV file path (e.g. "
              "--output results/my_sweep.csv)", file=sys.stderr)
        return 2
    if output.is_dir():
        print(f"error: --output {output}: is a folder; expected a CSV file path "
              "(e.g. --output results/my_sweep.csv)", file=sys.stderr)
        return 2
    if not output.parent.is_dir():
        print(f"error: --output {output}: no folder {output.parent}; expected a path in "
              "an existing folder", file=sys.stderr)
        return 2
    from replication.errors import InputError

    try:
        results = load_results(sweep_dir)
        check_one_experiment(results)
    except (InputError, SweepError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    rows = gather(sweep_dir, results)
    if not rows:
        print(f"error: {sweep_dir}: no result.json below it", file=sys.stderr)
        return 2
    for line in sweep_warnings(sweep_dir, [run for run, _ in results]):
        print(line, file=sys.stderr)
    metrics = args.metric
    if not metrics:  # the config's list is a default: plot those these runs have
        metrics = configured_metrics(results)
        numeric = numeric_columns(rows)
        for metric in [m for m in metrics if m not in numeric]:
            print(f"sweep_metrics: {metric} is not a numeric column of these results; "
                  "not plotted")
        metrics = [m for m in metrics if m in numeric]
    try:
        x = check_names(rows, metrics, args.x)
    except SweepError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    columns = sorted({key for row in rows for key in row},
                     key=lambda k: (k not in ("run", "experiment", "seed"), k))
    tmp = output.with_name(f".{output.name}.tmp")
    try:
        with open(tmp, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=columns)
            writer.writeheader()
            writer.writerows(rows)
        os.replace(tmp, output)
    finally:
        if tmp.exists():
            tmp.unlink()
    print(f"wrote {output} ({len(rows)} runs, {len(columns)} columns)")
    if args.no_plots:
        return 0
    if not metrics:
        print("no plots: pass --metric COLUMN or list sweep_metrics: in the experiment "
              f"config; numeric columns: {_few(numeric_columns(rows), 5)}")
    elif x is None:
        print("no plots: no override varies across the runs")
    else:
        for path in write_plots(rows, metrics, x, sweep_dir):
            print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
