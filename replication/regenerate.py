"""``replicate-all``: regenerate every figure, table and REPORT.md.

Runs each experiment that has a ``report`` block through the real command line
(``replicate experiment=NAME out=results/NAME force=true``: ``force`` lets a run write
into ``results/``), up to ``--jobs`` at a time. A result is
recomputed only when its resolved config, the code its runner imports
(:func:`replication.provenance.code_hash`) or an experiment it depends on
(``report.depends_on``) changed since it was made (:func:`stale_experiments`), so a fresh
clone recomputes nothing that its committed results already hold; ``--force`` recomputes
everything.

Scheduling: an experiment starts once every experiment it depends on has finished; among
those ready, the longest (by its last recorded time) starts first. Experiments marked
``report.exclusive: true`` (the benchmarks, whose timings are results) run with nothing
else running. ``report.gather: true`` experiments read the records written here, so they
run last, always. Each experiment's output is printed with its name in front and kept in
``results/.logs/NAME.log``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from replication.errors import InputError, one_line_error
from replication.interrupts import interruptible
from replication.machine import reference_seconds
from replication.progress import ENVIRONMENT, MODES, bar, check_environment, mode_for
from replication.provenance import PROJECT_ROOT, inputs_hash, run_provenance
from replication.report.build import CONFIG_DIR, PARTS, build_report, experiment_entries
from replication.results import read_result_or_none
from replication.workers import shared_threads

CACHE_FILE = ".regenerate-cache.json"


def resolved_configs(names, config_dir=CONFIG_DIR):
    """The resolved config of each experiment, exactly as ``replicate`` composes it.

    Parameters
    ----------
    names : list of str
        Experiment names.
    config_dir : str or Path
        ``configs/experiment`` (its parent is Hydra's config folder).

    Returns
    -------
    dict
        ``{name: resolved config}``.
    """
    import replication.cli  # noqa: F401  (registers the config resolvers)

    configs = {}
    with initialize_config_dir(config_dir=str(Path(config_dir).parent), version_base="1.3"):
        for name in names:
            cfg = compose(config_name="config", overrides=[f"experiment={name}"])
            configs[name] = OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)
    return configs


def experiment_keys(entries, configs):
    """Provenance (config, code and input hashes, as ``replicate`` writes them) and cache key
    (provenance plus the keys of the experiments it depends on) of each experiment.

    Parameters
    ----------
    entries : list of tuple
        ``(order, name, report block)`` of :func:`replication.report.build.experiment_entries`.
    configs : dict
        ``{name: resolved config}`` (:func:`resolved_configs`).

    Returns
    -------
    provenance, keys : dict
        ``{name: provenance}`` and ``{name: sha256 hex}``.
    """
    provenance, keys = {}, {}
    for _, name, block in entries:
        config = configs[name]
        provenance[name] = run_provenance(config)
        digest = hashlib.sha256(json.dumps(provenance[name], sort_keys=True).encode())
        for dependency in block.get("depends_on", []):
            digest.update(keys.get(dependency, dependency).encode())
        keys[name] = digest.hexdigest()
    return provenance, keys


def _read_json_object(path):
    """The JSON object in ``path``; ``{}`` (with a note) when it is missing or unreadable."""
    path = Path(path)
    if not path.exists():
        return {}
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        print(f"note: {path}: unreadable ({error}); ignored", file=sys.stderr)
        return {}
    if not isinstance(value, dict):
        print(f"note: {path}: not a JSON object; ignored", file=sys.stderr)
        return {}
    return value


def _cached(cache, name):
    """The cache entry of ``name`` (``{}`` when absent or in an older format)."""
    entry = cache.get(name)
    return entry if isinstance(entry, dict) else {}


def expected_seconds(results, cache, names):
    """Last recorded wall time of each experiment: the cache, else the last full run.

    Parameters
    ----------
    results : Path
        The results folder (``regenerate-full.json`` is read there).
    cache : dict
        The contents of ``.regenerate-cache.json``.
    names : iterable of str
    """
    recorded = _read_json_object(results / "regenerate-full.json").get("experiments", {})
    recorded = recorded if isinstance(recorded, dict) else {}
    expected = {}
    for name in names:
        seconds = _cached(cache, name).get("seconds", recorded.get(name))
        expected[name] = float(seconds) if isinstance(seconds, (int, float)) else 0.0
    return expected


def with_dependencies(names, blocks):
    """``names`` and every experiment they depend on, directly or not (``depends_on``).

    Parameters
    ----------
    names : iterable of str
    blocks : dict
        ``{name: report block}``.
    """
    needed, pending = set(), list(names)
    while pending:
        name = pending.pop()
        if name not in needed:
            needed.add(name)
            pending.extend(blocks.get(name, {}).get("depends_on", []))
    return needed


def stale_experiments(entries, results, provenance, keys, cache, *, force=False, cascade=True):
    """Names of the experiments to recompute.

    A result is current when it exists (an unreadable ``result.json`` counts as missing),
    carries the provenance (config, code and input hashes) this config, code and data
    give, and no experiment it depends on is recomputed; the cache
    of keys (which include the dependencies' keys) catches a dependency recomputed by an
    earlier, interrupted run. Without a cache (a fresh clone) the committed results
    whose provenance matches are current.

    Parameters
    ----------
    entries : list of tuple
        ``(order, name, report block)``.
    results : Path
        Folder of ``NAME/result.json``.
    provenance, keys : dict
        From :func:`experiment_keys`.
    cache : dict
        The contents of ``.regenerate-cache.json`` (``{}`` on a fresh clone).
    force : bool
        Every experiment is stale.
    cascade : bool
        Whether an experiment is stale because one it depends on is (``False``: only the
        experiments stale by themselves).
    """
    current = {}
    for _, name, _ in entries:
        result = read_result_or_none(results / name / "result.json")
        current[name] = (not force and result is not None
                         and result.get("provenance") == provenance[name]
                         and _cached(cache, name).get("key", keys[name]) == keys[name])
    stale = set()
    changed = True
    while changed:  # to a fixed point: dependencies may come later in report order
        changed = False
        for _, name, block in entries:
            if name in stale:
                continue
            if not current[name] or (cascade and any(d in stale
                                                     for d in block.get("depends_on", []))):
                stale.add(name)
                changed = True
    return stale


def stale_now(results="results", cache=None):
    """The experiments of ``replicate-all`` that a run without ``--force`` would recompute
    now, in report order (gathered ones, which always run, left out).

    Parameters
    ----------
    results : str or Path
        Folder of ``NAME/result.json``.
    cache : dict, optional
        The contents of ``.regenerate-cache.json``; ``None``: as on a fresh clone, which
        has none (committed results count by their provenance alone).
    """
    entries = experiment_entries()
    configs = resolved_configs([name for _, name, _ in entries])
    provenance, keys = experiment_keys(entries, configs)
    stale = stale_experiments(entries, Path(results), provenance, keys, cache or {})
    return [name for _, name, block in entries if name in stale and not block.get("gather")]


class _Job:
    """One ``replicate`` subprocess whose output is echoed with a prefix and logged."""

    def __init__(self, name, command, log_dir, echo, env=None):
        self.name = name
        self.start = time.perf_counter()
        Path(log_dir).mkdir(parents=True, exist_ok=True)
        self.log_path = Path(log_dir) / f"{name}.log"
        self.process = subprocess.Popen(command, cwd=PROJECT_ROOT, stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True, bufsize=1,
                                        env=env)
        self.reader = threading.Thread(target=self._pump, args=(echo,), daemon=True)
        self.reader.start()

    def _pump(self, echo):
        with open(self.log_path, "w") as log:
            for line in self.process.stdout:
                log.write(line)
                if echo:
                    print(f"    {self.name} | {line.rstrip()}", flush=True)

    def finish(self, status, usage):
        """Record the exit ``status`` and ``usage`` from ``os.wait4``; return
        ``(exit code, wall seconds, cpu seconds)``."""
        self.process.returncode = os.waitstatus_to_exitcode(status)
        self.reader.join()
        self.process.stdout.close()
        wall = time.perf_counter() - self.start
        return self.process.returncode, wall, usage.ru_utime + usage.ru_stime


def _tail(path, lines=15):
    text = Path(path).read_text().splitlines() if Path(path).exists() else []
    return "\n".join(f"      {line}" for line in text[-lines:])


def replicate_command(results):
    """``command_for(name)`` of :func:`run_scheduled`: the real ``replicate`` run."""
    def command_for(name):
        return [sys.executable, "-m", "replication.cli", f"experiment={name}",
                f"out={Path(results) / name}", "force=true"]
    return command_for


def critical_paths(names, blocks, expected):
    """Expected seconds from the start of each experiment to the end of the longest chain
    of experiments that depend on it (its own time plus the longest of its dependents'):
    starting the longest chains first keeps a long study from waiting on its data.

    Parameters
    ----------
    names : list of str
    blocks : dict
        ``{name: report block}`` (``depends_on``).
    expected : dict
        ``{name: seconds}``; a missing name counts 0.
    """
    dependents = {name: [n for n in names if name in blocks[n].get("depends_on", [])]
                  for name in names}
    paths = {}

    def path(name, seen=()):
        if name not in paths:
            if name in seen:  # a cycle: run_scheduled refuses it
                return 0.0
            paths[name] = expected.get(name, 0.0) + max(
                (path(d, seen + (name,)) for d in dependents[name]), default=0.0)
        return paths[name]

    return {name: path(name) for name in names}


def run_scheduled(todo, blocks, *, jobs, expected, command_for, log_dir, echo=True,
                  child_progress="plain", recheck=(), still_stale=None):
    """Run experiments ``todo`` (names) with ``command_for(name)`` (an argv list), up to
    ``jobs`` at once, respecting ``depends_on`` and ``exclusive`` of ``blocks[name]``;
    return ``{name: (exit status, wall seconds, cpu seconds)}``.

    Ready experiments start longest chain first (:func:`critical_paths` of ``expected``
    seconds). An experiment whose dependency failed is not run (status ``None``). An
    experiment of ``recheck`` is run only if ``still_stale(name)`` says so once its
    dependencies have finished (else status ``"current"``). A bar ("experiments") counts
    the finished ones.

    Parameters
    ----------
    todo : list of str
        Experiment names.
    blocks : dict
        ``{name: report block}`` (``depends_on``, ``exclusive``).
    jobs : int
        Experiments run at once.
    expected : dict
        ``{name: seconds}`` of the last runs, for the order.
    command_for : callable
        ``name -> argv list``.
    log_dir : Path
        Where ``NAME.log`` goes.
    echo : bool
        Print each experiment's output, prefixed with its name.
    child_progress : str
        Progress mode of the experiments (``REPLICATION_PROGRESS``): their output is a
        pipe, so ``plain`` lines or ``none``.
    recheck : collection of str
        Experiments stale only because one they depend on is.
    still_stale : callable, optional
        ``name -> bool``, asked for each of ``recheck`` when it is ready to start.
    """
    with bar(len(todo), "experiments") as shown:
        return _run_scheduled(todo, blocks, jobs=jobs, expected=expected,
                              command_for=command_for, log_dir=log_dir, echo=echo,
                              environ={**os.environ, ENVIRONMENT: child_progress},
                              shown=shown, recheck=set(recheck), still_stale=still_stale)


def _run_scheduled(todo, blocks, *, jobs, expected, command_for, log_dir, echo, environ,
                   shown, recheck, still_stale):
    pending = list(todo)
    priority = critical_paths(todo, blocks, expected)
    shared_env = shared_threads(environ, jobs)   # replication.workers: why
    running, outcome = {}, {}
    total = len(pending)

    def blocked(name):
        return [d for d in blocks[name].get("depends_on", []) if d in pending or
                any(job.name == d for job in running.values())]

    while pending or running:
        for name in [n for n in pending
                     if any(outcome.get(d, (0,))[0] not in (0,)
                            for d in blocks[n].get("depends_on", []))]:
            pending.remove(name)
            outcome[name] = (None, 0.0, 0.0)
            shown.update()
            print(f"[{len(outcome)}/{total}] {name}: not run (a dependency failed)", flush=True)
        ready = sorted((n for n in pending if not blocked(n)), key=lambda n: -priority[n])
        exclusive_running = any(blocks[j.name].get("exclusive") for j in running.values())
        for name in ready:
            if len(running) >= jobs or exclusive_running:
                break
            if blocks[name].get("exclusive") and running:
                continue
            pending.remove(name)
            if name in recheck and not still_stale(name):
                outcome[name] = ("current", 0.0, 0.0)
                shown.update()
                print(f"[{len(outcome)}/{total}] {name}: up to date (what it reads from the "
                      "experiments it depends on did not change)", flush=True)
                continue
            job = _Job(name, command_for(name), log_dir, echo,
                       env=environ if blocks[name].get("exclusive") else shared_env)
            running[job.process.pid] = job
            print(f"[start] {name}" + (" (alone: its timings are results)"
                                       if blocks[name].get("exclusive") else ""), flush=True)
            exclusive_running = bool(blocks[name].get("exclusive"))
        if not running:
            if pending:  # only possible with a dependency cycle or an unknown dependency
                raise RuntimeError(f"cannot schedule {pending}: check report.depends_on")
            break
        pid, status, usage = os.wait4(-1, 0)
        job = running.pop(pid, None)
        if job is None:
            continue
        outcome[job.name] = job.finish(status, usage)
        shown.update()
        code, wall, cpu = outcome[job.name]
        label = f"[{len(outcome)}/{total}] {job.name}"
        if code == 0:
            print(f"{label}: done in {wall:.1f} s ({cpu:.0f} s of CPU)", flush=True)
        else:
            print(f"{label}: FAILED (exit {code}); last lines of {job.log_path}:\n"
                  f"{_tail(job.log_path)}", flush=True)
    return outcome


def _why_stale(name, results, provenance, stale, by_themselves, blocks, force):
    """Why ``name`` is to be recomputed, in a few words (``--dry-run``)."""
    if force:
        return "--force"
    if name not in by_themselves:
        # a real run checks again once those have run (still_stale), and may skip it
        return ("if what it reads changes: depends on "
                + ", ".join(d for d in blocks[name].get("depends_on", []) if d in stale))
    result = read_result_or_none(results / name / "result.json")
    if result is None:
        return "no result"
    had = result.get("provenance") or {}
    changed = [what for key, what in (("config_sha256", "config"), ("code_sha256", "code"),
                                      ("inputs_sha256", "inputs"))
               if had.get(key) != provenance[name].get(key)]
    if changed:
        return " and ".join(changed) + " changed"
    if had != provenance[name]:
        return "its provenance record differs (an older result)"
    # current by its own provenance: the cache key, which holds its dependencies' keys, differs
    again = [d for d in blocks[name].get("depends_on", []) if d in stale]
    if again:
        return (f"depends on {', '.join(again)}, which "
                f"{'runs' if len(again) == 1 else 'run'} again")
    return "an experiment it depends on was recomputed by an interrupted run"


def _seconds(seconds):
    """``123 s``, or ``unknown`` without a recorded time (:func:`expected_seconds`: 0)."""
    return f"{seconds:.0f} s" if seconds else "unknown"


def main(argv=None):
    """Regenerate results (cached), figures and REPORT.md."""
    try:
        with interruptible():  # a Ctrl-C that lands in an import is not lost
            return _main(argv)
    except KeyboardInterrupt:  # the experiments running got Ctrl-C too and wrote nothing
        print("error: interrupted; finished experiments keep their results, the next run "
              "redoes the others", file=sys.stderr)
        return 130


def _main(argv=None):
    parser = argparse.ArgumentParser(prog="replicate-all", description=main.__doc__)
    parser.add_argument("--force", action="store_true", help="recompute every result")
    parser.add_argument("--only", default=None, help="comma-separated experiment names")
    parser.add_argument("--part", default=None,
                        help="comma-separated parts of the report (each experiment's "
                             f"report.part): {', '.join(PARTS)}; e.g. --part paper "
                             "regenerates the paper's own figures and tables")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                        help="experiments run at once (default: the number of CPUs)")
    parser.add_argument("--quiet", action="store_true",
                        help="do not echo the experiments' own output (it is still logged) "
                             "and show no progress bar")
    parser.add_argument("--progress", choices=MODES, default="auto",
                        help="the bar over experiments: bar (live), plain (a line every few "
                             "seconds), none; auto: bar on a terminal, else plain. The "
                             "experiments' logs get plain lines (none with --progress=none)")
    parser.add_argument("--results", default="results",
                        help="results folder (default results/); another folder gets its own "
                             "REPORT.md, and the runs still write the figures and data "
                             "their configs name")
    parser.add_argument("--dry-run", action="store_true",
                        help="list the experiments a run would recompute and why (config, "
                             "code or inputs changed, no result, an experiment it depends "
                             "on), then stop; runs and writes nothing")
    parser.error = one_line_error
    args = parser.parse_args(argv)
    if not args.results.strip():
        print(f"error: --results={args.results!r}: expected a folder (default results/)",
              file=sys.stderr)
        return 2
    if args.jobs < 1:
        print(f"error: --jobs={args.jobs}: expected at least 1", file=sys.stderr)
        return 2
    try:
        check_environment()
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2

    results = Path(args.results)
    entries = experiment_entries()
    blocks = {name: block for _, name, block in entries}
    only = {name for name in (args.only or "").split(",") if name}
    if args.only is not None and not only:
        print(f"error: --only={args.only!r}: no experiment named; expected NAME[,NAME] "
              "(leave --only out to regenerate everything)", file=sys.stderr)
        return 2
    parts = []
    if args.part is not None:
        if args.only is not None:
            print("error: --only and --part: give one of them", file=sys.stderr)
            return 2
        parts = [part for part in args.part.split(",") if part]
        unknown = sorted(set(parts) - set(PARTS))
        if not parts or unknown:
            print(f"error: --part={args.part!r}: expected PART[,PART] of "
                  f"{', '.join(PARTS)}", file=sys.stderr)
            return 2
        only = {name for name, block in blocks.items() if block.get("part") in parts}
        if not only:
            print(f"error: --part={args.part!r}: no experiment config has that report.part",
                  file=sys.stderr)
            return 2
    unknown = only - set(blocks)
    if unknown:
        from replication.cli import available_experiments

        outside = sorted(unknown & set(available_experiments()))
        if outside:
            print(f"error: --only: {outside} not part of replicate-all (no report block in "
                  "the config); run it with replicate experiment=NAME", file=sys.stderr)
        else:
            print(f"error: --only: unknown experiment(s) {sorted(unknown)}; known: "
                  f"{sorted(blocks)}", file=sys.stderr)
        return 2
    if not args.dry_run:
        try:
            results.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            print(f"error: --results={results}: cannot make that folder "
                  f"({error.strerror or error})", file=sys.stderr)
            return 2
    cache_path = results / CACHE_FILE
    cache = _read_json_object(cache_path)
    # the machine's speed now (replication/machine.py), outside the run's timed seconds
    reference = None if args.dry_run else reference_seconds()
    start = time.perf_counter()
    gathered = [name for _, name, block in entries if block.get("gather")]
    # with --only, the named experiments and those they depend on (their keys hold the
    # dependencies' keys): composing and hashing all of them takes seconds each
    if only:
        needed = with_dependencies(only, blocks)
        entries = [entry for entry in entries if entry[1] in needed]
    configs = resolved_configs([name for _, name, _ in entries])
    provenance, keys = experiment_keys(entries, configs)
    stale = stale_experiments(entries, results, provenance, keys, cache, force=args.force)
    by_themselves = stale_experiments(entries, results, provenance, keys, cache,
                                      force=args.force, cascade=False)

    def still_stale(name):
        """Whether ``name``, current by itself, reads changed inputs now that the
        experiments it depends on have run."""
        result = read_result_or_none(results / name / "result.json")
        # its config and code were current (by_themselves): only the inputs can differ
        now = {**provenance[name], "inputs_sha256": inputs_hash(configs[name])}
        return result is None or result.get("provenance") != now
    todo, timings, cpu = [], {}, {}
    for _, name, _ in entries:
        if (only and name not in only) or name in gathered:
            continue
        if name not in stale:
            print(f"{name}: up to date", flush=True)
            timings[name] = "up to date"
        else:
            todo.append(name)
    expected = expected_seconds(results, cache, blocks)
    if args.dry_run:
        for name in todo:
            why = _why_stale(name, results, provenance, stale, by_themselves, blocks,
                             args.force)
            print(f"{name}: would run ({why}; last time {_seconds(expected.get(name))})",
                  flush=True)
        print(f"{len(todo)} experiment(s) would run, then {', '.join(gathered) or 'none'} "
              "(always) and REPORT.md; nothing was run or written (--dry-run)", flush=True)
        return 0
    print(f"{len(todo)} experiment(s) to run, {args.jobs} at a time", flush=True)
    with mode_for("none" if args.quiet else args.progress):
        outcome = run_scheduled(todo, blocks, jobs=args.jobs, expected=expected,
                                command_for=replicate_command(results),
                                log_dir=results / ".logs", echo=not args.quiet,
                                child_progress="none" if args.progress == "none" else "plain",
                                recheck=stale - by_themselves, still_stale=still_stale)
    if todo:
        # the keys again: an experiment's inputs may be the outputs of one that ran just now
        # (table_result, single_result), and a key from before would make it stale next time
        provenance, keys = experiment_keys(entries, configs)
    failures = []
    for name in todo:  # report order
        code, wall, cpu_seconds = outcome[name]
        if code == "current":
            cache[name] = {**_cached(cache, name), "key": keys[name]}
            timings[name] = "up to date"
        elif code == 0:
            cache[name] = {"key": keys[name], "seconds": wall}
            timings[name], cpu[name] = wall, cpu_seconds
        else:
            failures.append(name)
            cache.pop(name, None)
    cache_path.write_text(json.dumps(cache, indent=1, sort_keys=True))
    record = {"total_seconds": time.perf_counter() - start, "experiments": timings,
              "cpu_seconds": cpu, "jobs": args.jobs, "cpu_count": os.cpu_count(),
              "forced": args.force, "only": sorted(only), "parts": parts,
              "failures": failures,
              "machine_reference_seconds": reference}
    text = json.dumps(record, indent=1) + "\n"
    (results / "regenerate.json").write_text(text)
    if not failures and "up to date" not in timings.values():
        if not only:
            (results / "regenerate-full.json").write_text(text)
        elif parts:   # every experiment of these parts recomputed
            name = "+".join(part for part in PARTS if part in parts)
            (results / f"regenerate-part-{name}.json").write_text(text)
    if only and not failures:
        # a run of some experiments rewrites files that others read (their inputs'
        # hashes hold every file of a result folder, timings included): say which are
        # not current now (for that reason or another), so that none is left unnoticed
        outside = [name for name in stale_now(results, cache) if name not in only]
        if outside:
            print(f"note: {len(outside)} experiment(s) outside this run are not current "
                  f"(what they read may have been rewritten by it; `replicate-all "
                  f"--dry-run` says why): {', '.join(outside)}; `replicate-all` brings "
                  "them up to date", flush=True)
    for name in gathered:  # gatherers read the records above, so they run last, always
        command = replicate_command(results)(name)
        if subprocess.run(command, cwd=PROJECT_ROOT, check=False).returncode != 0:
            failures.append(name)
    # the project's REPORT.md is built from the project's results only
    report_path = (PROJECT_ROOT / "REPORT.md"
                   if results.resolve() == (PROJECT_ROOT / "results").resolve()
                   else results / "REPORT.md")
    report_path.write_text(build_report(results))
    print(f"wrote {report_path} ({time.perf_counter() - start:.1f} s in all)")
    if failures:
        print(f"error: {len(failures)} experiment(s) failed: {', '.join(failures)}",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
