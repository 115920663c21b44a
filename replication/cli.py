"""``replicate``: the Hydra entry point (docs/results.md).

The only module that sees a DictConfig. Each experiment config names a ``runner``
(``module:function``); the runner receives the resolved config as a plain dict and the
output folder, returns its result keys, and this module adds the common keys and writes
``result.json`` atomically.

Boundaries (docs/results.md, "Refusals, warnings, interruptions"): the config is checked
(:mod:`replication.guard`) before any work, Hydra's own refusals included; the runner
writes into a staging folder whose files are moved to ``out`` (and to ``figure_dir`` /
``data_dir``) only when it succeeds; Ctrl-C ends the run with status 130 and nothing
written; ``limits.max_seconds`` bounds the run's time.
"""

from __future__ import annotations

import ast
import errno
import functools
import importlib
import os
import shutil
import signal
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from replication.errors import InputError, check
from replication.guard import (LIMITS, OUTPUT_KEYS, check_config, check_out, check_writable,
                               committed_folder)
from replication.interrupts import interruptible
from replication.progress import mode_for
from replication.provenance import run_provenance
from replication.results import (package_versions, read_result_or_none, to_jsonable,
                                 write_json_atomic)

CONFIG_DIR = str(Path(__file__).resolve().parent.parent / "configs")

# config keys naming output files in a folder of their own (``figure: figures/x.png``; a
# bare name is a file inside ``figure_dir``): staged in a folder of their own
OUTPUT_FILE_KEYS = ("figure", "manifest")


def _output_file(config, key):
    """``config[key]`` when it names an output file with a folder, else ``None``."""
    value = config.get(key)
    if isinstance(value, str) and value and Path(value).parent != Path("."):
        return Path(value)
    return None


_MOVED_NAMES = {"figure_dir": "figures", "figures_dir": "figures", "data_dir": "data"}


def keep_committed(config, out):
    """``(config, notes)``: ``config`` with every output folder and file aimed at a
    committed folder (``results/``, ``figures/``, ``synthetic_data/``) moved into ``out``,
    and per move ``(new path, note)``, the note to print once the run has written there;
    ``force=true`` keeps them. A run
    with ``out=DIR`` does not replace the committed data and figures that later runs and
    ``replicate-all`` read.

    Parameters
    ----------
    config : dict
        The resolved config (plain dict).
    out : str or Path
        The run's output folder.
    """
    notes = []
    if config.get("force"):
        return config, notes
    kept = dict(config)
    for key in OUTPUT_KEYS + OUTPUT_FILE_KEYS:
        value = (config.get(key) if key in OUTPUT_KEYS else _output_file(config, key))
        if not (isinstance(value, (str, Path)) and str(value)):
            continue
        folder = committed_folder(value)
        if folder is None:
            continue
        moved = Path(out) / (_MOVED_NAMES[key] if key in OUTPUT_KEYS else Path(value).name)
        kept[key] = str(moved)
        notes.append((moved, f"note: {key}={value} is in the committed {folder}; this run "
                             f"wrote {moved} instead (force=true writes the committed "
                             "one when the run reads the suite's own data)"))
    return kept, notes

if not OmegaConf.has_resolver("or_default"):
    OmegaConf.register_new_resolver("or_default", lambda value, default: value or default)


def folder_name(text):
    """``text`` as one folder name: ``%`` and ``/`` written ``%25`` and ``%2F`` (a sweep
    over ``data.path=dir/a.npz,...`` otherwise nests its run folders; ``replicate-gather``
    reads the values back)."""
    return str(text).replace("%", "%25").replace("/", "%2F")


if not OmegaConf.has_resolver("folder_name"):
    OmegaConf.register_new_resolver("folder_name", folder_name)


def available_experiments():
    """Names of the experiment configs in ``configs/experiment``."""
    return sorted(p.stem for p in (Path(CONFIG_DIR) / "experiment").glob("*.yaml"))


def resolve_runner(spec):
    """Import ``module:function``."""
    module_name, _, function_name = spec.partition(":")
    return getattr(importlib.import_module(module_name), function_name)


def experiment_defaults(name):
    """The resolved config of experiment ``name`` without any other override."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    overrides = [f"experiment={name}"]
    if GlobalHydra.instance().is_initialized():
        cfg = compose(config_name="config", overrides=overrides)
    else:
        with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
            cfg = compose(config_name="config", overrides=overrides)
    return OmegaConf.to_container(cfg, resolve=True)


class Staging:
    """A hidden folder next to ``out`` that receives everything a runner writes.

    :meth:`commit` moves its files to ``out`` and to the configured output folders
    (``figure_dir``, ``data_dir``) and files (``figure``, ``manifest``), with the staging
    paths in JSON files and in the result replaced by the real ones; :meth:`discard`
    removes it.
    """

    def __init__(self, config, out):
        self.out = Path(out)
        anchor = self.out.parent
        while not anchor.exists() and anchor.parent != anchor:
            anchor = anchor.parent
        self.root = Path(tempfile.mkdtemp(prefix=f".{self.out.name or 'out'}.partial-"
                                          f"{_sweep().get('id', '')}",
                                          dir=anchor)).resolve()
        self.targets = {self.root / "out": self.out}
        self.config = dict(config)
        for key in OUTPUT_KEYS:
            value = config.get(key)
            if isinstance(value, str) and value:
                staged = self.root / key
                self.targets[staged] = Path(value)
                self.config[key] = str(staged)
        for key in OUTPUT_FILE_KEYS:
            value = _output_file(config, key)
            if value is not None:
                staged = self.root / f"{key}_file"
                self.targets[staged] = value.parent
                self.config[key] = str(staged / value.name)
        for staged in self.targets:
            staged.mkdir()

    def _replacements(self):
        pairs = [(str(staged), str(real)) for staged, real in self.targets.items()]
        return sorted(pairs, key=lambda pair: -len(pair[0]))

    def fix(self, value):
        """``value`` (a result) with every staging path replaced by the real one."""
        if isinstance(value, dict):
            return {k: self.fix(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [self.fix(v) for v in value]
        if isinstance(value, str):
            for staged, real in self._replacements():
                value = value.replace(staged, real)
        return value

    def _fix_json(self, path):
        import json

        text = path.read_text()
        for staged, real in self._replacements():
            text = text.replace(json.dumps(staged)[1:-1], json.dumps(real)[1:-1])
        path.write_text(text)

    def commit(self, result_name="result.json"):
        """Move every staged file to its real place, ``out/result.json`` last;
        ``self.filled``: the real folders that received a file."""
        moves = []
        for staged, real in self.targets.items():
            for item in sorted(staged.rglob("*")):
                if not item.is_dir():
                    moves.append((item, real / item.relative_to(staged)))
        self.filled = {target.parent for _, target in moves}
        last = self.root / "out" / result_name
        moves.sort(key=lambda move: move[0] == last)
        for item, target in moves:
            if item.suffix == ".json" and item != last:
                self._fix_json(item)
            target.parent.mkdir(parents=True, exist_ok=True)
            try:
                os.replace(item, target)
            except OSError as error:
                if error.errno != errno.EXDEV:
                    raise
                shutil.move(str(item), str(target))
        self.discard()

    def discard(self):
        shutil.rmtree(self.root, ignore_errors=True)


class TimeLimit(InputError):
    """The run took longer than ``limits.max_seconds``."""


@contextmanager
def time_limit(seconds):
    """Raise :class:`TimeLimit` in the main thread after ``seconds`` (no limit elsewhere)."""
    def expire(signum, frame):
        raise TimeLimit(f"limits.max_seconds={seconds:g}: the run took longer; raise the "
                        "limit (limits.max_seconds=S) or use smaller settings")

    try:
        previous = signal.signal(signal.SIGALRM, expire)
    except ValueError:  # not the main thread
        yield
        return
    signal.setitimer(signal.ITIMER_REAL, float(seconds))
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def report_warnings(result, strict):
    """Print the runner's ``warnings`` on stderr; with ``strict`` refuse the run.

    Parameters
    ----------
    result : dict
        The runner's result; its ``warnings`` (a list of strings) are printed.
    strict : bool
        ``strict=true``: a warning refuses the run.

    Raises
    ------
    InputError
        With ``strict`` and at least one warning (the first one names the refusal).
    """
    warnings = [str(w) for w in result.get("warnings") or []]
    if strict and warnings:
        more = f" (and {len(warnings) - 1} more warning(s))" if len(warnings) > 1 else ""
        raise InputError(f"strict=true: {warnings[0]}{more}")
    for warning in warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return warnings


def run_experiment(config, out, defaults=None, overrides=None):
    """Run the experiment described by the plain-dict ``config``; return the result dict.

    ``defaults``: the experiment's own config (without overrides), against which the
    config's types are checked; composed here when not given.

    Parameters
    ----------
    config : dict
        The resolved config (plain dict), with ``runner``, ``name`` and ``out``.
    out : str or Path
        Where ``result.json`` goes (written atomically, after every other file).
    defaults : dict, optional
        The experiment's own config, without overrides.
    overrides : list of str, optional
        The command line's overrides of this run (a sweep's job: its own), kept in the
        result as ``overrides`` (``replicate-gather`` reads a job's settings from them).
    """
    if not config.get("runner"):
        raise InputError(
            "no experiment chosen: pass experiment=NAME, one of "
            + ", ".join(available_experiments())
        )
    if defaults is None and config.get("name") in available_experiments():
        defaults = experiment_defaults(config["name"])
    check_config(config, defaults)
    check_out(str(out), force=config.get("force", False))
    check_writable(out)
    runner = resolve_runner(config["runner"])
    provenance = run_provenance(config)
    previous = read_result_or_none(Path(out) / "result.json") if config.get("resume") \
        else None
    if previous is not None and previous.get("provenance") == provenance:
        # the kept result answers as a new run would: strict=true refuses its warnings
        report_warnings(previous, config.get("strict", False))
        print(f"up to date: {Path(out) / 'result.json'} (resume=true)", file=sys.stderr)
        return previous
    config, notes = keep_committed(config, out)
    staging = Staging(config, out)
    try:
        with time_limit(LIMITS["max_seconds"]), mode_for(config.get("progress")):
            start = time.perf_counter()
            result = runner(staging.config, staging.root / "out")
            wall = time.perf_counter() - start
        result = staging.fix(to_jsonable(result))
        warnings = report_warnings(result, config.get("strict", False))
        payload = {
            "experiment": config.get("name"),
            "config": config,
            "seed": config.get("seed"),
            "versions": package_versions(),
            "wall_seconds": wall,
            "provenance": provenance,
        }
        if overrides is not None:
            payload["overrides"] = [str(line) for line in overrides]
        payload.update(result)
        payload["warnings"] = warnings
        write_json_atomic(staging.root / "out" / "result.json", payload)
        staging.commit()
    finally:
        staging.discard()
    for moved, note in notes:
        if moved.exists():  # an output key the runner does not use leaves nothing
            print(note, file=sys.stderr)
    _note_unused_figure_dir(config, defaults, result, staging.filled)
    print(f"wrote {Path(out) / 'result.json'}", file=sys.stderr)
    return payload


def _note_unused_figure_dir(config, defaults, result, filled):
    """A note when ``figure_dir`` was set (unlike the experiment's own config) but the run
    drew its figures elsewhere (a user's sequence: ``out/figures``), not silently."""
    value = config.get("figure_dir")
    figures = [Path(p) for p in result.get("figures") or [] if isinstance(p, str)]
    if (not value or not figures or value == (defaults or {}).get("figure_dir")
            or any(Path(value) == folder or Path(value) in folder.parents
                   for folder in filled)):
        return
    print(f"note: figure_dir={value} got no figure: this run drew them in "
          f"{figures[0].parent} (figure_dir is for the experiment's default data)",
          file=sys.stderr)


def _error(message, status=2):
    print(f"error: {message}", file=sys.stderr, flush=True)
    sys.exit(status)


def _os_message(error):
    where = f"{error.filename}: " if error.filename else ""
    if error.errno == errno.ENOSPC:
        return f"{where}no space left on device; nothing written"
    return f"{where}{error.strerror or error}"


def _interrupted(sweep=False):
    """Leave at once with status 130 (no interpreter teardown with numba threads busy).
    ``sweep``: the jobs that finished before keep their results."""
    print("error: interrupted; " + ("the jobs stopped wrote nothing, those that finished "
                                    "kept their results (resume=true runs the rest)"
                                    if sweep else "nothing written"),
          file=sys.stderr, flush=True)
    sys.stdout.flush()
    os._exit(130)


def _drop_empty_job_folder():
    """In a sweep, remove the job folder Hydra made for a refused job when it is empty."""
    from hydra.types import RunMode

    try:
        hydra_config = HydraConfig.get()
        if hydra_config.mode == RunMode.MULTIRUN:
            Path(hydra_config.runtime.output_dir).rmdir()
    except (OSError, ValueError):
        pass


@hydra.main(config_path=CONFIG_DIR, config_name="config", version_base="1.3")
def _hydra_main(cfg: DictConfig):
    try:
        _run_task(cfg)
    except BaseException:
        _drop_empty_job_folder()
        raise


SWEEP_ENVIRONMENT = "REPLICATION_SWEEP"   # set by replicate for the jobs of its sweep


def _sweep():
    """``{"id", "refused"}`` of the sweep this process runs a job of (:func:`main` sets
    :data:`SWEEP_ENVIRONMENT` for its launchers' workers, and the Dask launcher sends it
    with each job); ``{}`` outside one, or in a worker that did not get it."""
    import json

    try:
        value = json.loads(os.environ.get(SWEEP_ENVIRONMENT, "{}"))
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def _in_worker():
    """Whether this job runs in a sweep under a launcher other than Hydra's basic one
    (joblib, submitit, Dask: each job in a process of its own) that knows its sweep
    (:func:`_sweep`)."""
    from hydra.types import RunMode

    try:
        hydra_config = HydraConfig.get()
    except ValueError:
        return False
    return (hydra_config.mode == RunMode.MULTIRUN and "refused" in _sweep()
            and not str(hydra_config.launcher._target_).endswith("BasicLauncher"))


def _refuse(message):
    """A refused run: its ``error:`` line and status 2. In a launcher's worker the job
    ends instead (its empty folder removed) with the message in its sweep's own folder
    of refusals (:func:`_sweep`), which the submitting ``replicate`` reads when every job
    is back (:func:`_report_refused`): a job that exits would stop the jobs running beside
    it (joblib) or end the sweep in a traceback (submitit). A worker without that folder
    (a launcher that does not pass :data:`SWEEP_ENVIRONMENT` to workers started before the
    sweep; the suite's Dask launcher passes it) exits as a single run does."""
    if not _in_worker():
        _error(message)
        return
    print(f"error: {message}", file=sys.stderr, flush=True)
    hydra_config = HydraConfig.get()
    folder = Path(_sweep()["refused"])
    folder.mkdir(parents=True, exist_ok=True)
    overrides = ",".join(str(o) for o in hydra_config.overrides.task)
    write_json_atomic(folder / f"{hydra_config.job.num}.json",
                      {"job": hydra_config.job.num, "overrides": overrides,
                       "message": str(message)})
    _drop_empty_job_folder()


def _refused_jobs(folder):
    """The refusals (:func:`_refuse`) in ``folder``, job by job, which is then removed;
    ``[]`` when there are none."""
    import json

    folder = Path(folder)
    refused = []
    for path in sorted(folder.glob("*.json")) if folder.is_dir() else []:
        try:
            refused.append(json.loads(path.read_text()))
            path.unlink()
        except (OSError, ValueError):
            continue
    _remove_empty([folder])
    return sorted(refused, key=lambda item: item.get("job", 0))


def _run_task(cfg):
    try:
        config = OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)
        out = config["out"]
        if out is None:
            out = HydraConfig.get().runtime.output_dir
        config["out"] = out
        run_experiment(config, out, overrides=list(HydraConfig.get().overrides.task))
    except InputError as error:
        _refuse(error)
    except FileNotFoundError as error:
        _refuse(f"{error.filename}: file not found")
    except OSError as error:
        _refuse(_os_message(error))
    except SystemError as error:  # Ctrl-C or the time limit inside numba's dispatcher
        cause = error.__cause__ or error.__context__
        if isinstance(cause, KeyboardInterrupt):
            raise KeyboardInterrupt from None
        if isinstance(cause, InputError):
            _refuse(cause)
            return
        raise


@contextmanager
def composing(overrides=(), explain=True):
    """Hydra's ``compose`` for the suite's configs (``compose(config_name="config",
    overrides=[...])``), with Hydra's and OmegaConf's refusals as one
    :class:`InputError` line (with ``explain``, :func:`_hydra_message`'s, which spells
    ``overrides``' unknown keys; else the refusal's own text)."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
            yield compose
    except InputError:
        raise
    except (HydraException, OmegaConfBaseException, ValueError) as error:
        raise InputError(_hydra_message(error, list(overrides)) if explain
                         else str(error)) from None
    finally:
        GlobalHydra.instance().clear()


def _own_config(compose, name, resolve=True, hydra=False):
    """The config of experiment ``name`` as its file composes it, without the command
    line's overrides (a dict; with ``hydra``, Hydra's own block too)."""
    return OmegaConf.to_container(compose(config_name="config",
                                          overrides=[f"experiment={name}"],
                                          return_hydra_config=hydra), resolve=resolve)


def _experiment_config(overrides, hydra=False):
    """The chosen experiment's composed config (a dict; with ``hydra``, Hydra's own block
    too) from ``overrides`` (``experiment=NAME``, the first of a sweep's), or ``None``
    (none chosen, or Hydra refuses it)."""
    chosen = [o.split("=", 1)[1].split(",")[0] for o in overrides
              if "=" in o and o.split("=", 1)[0].lstrip("+~") == "experiment"]
    if not chosen:
        return None
    try:
        with composing(explain=False) as compose:
            return _own_config(compose, chosen[-1], resolve=False, hydra=hydra)
    except InputError:   # a hint only: no hint rather than another error
        return None


class CodeSettings:
    """What the code behind a runner reads of a config (:func:`code_settings`).

    - ``names``: ``(block, NAME)`` of each ``BLOCK.get("NAME")`` or ``.pop("NAME")``, the
      block as the code names it (``cost_cfg``, ``config["cost"]``, ``config.get("data")``);
    - ``groups``: ``{group: keys}`` of its ``*GROUPS`` dicts (a block of groups,
      ``method.pyramid``, each merged over its own defaults);
    - ``named``: ``{name: keys}`` of its ``NAME_DEFAULTS`` dicts (block ``name``);
    - ``plain``: the keys of its ``DEFAULTS`` dicts (merged over a block holding some of
      their keys);
    - ``whole``: blocks it takes whole, so any key of theirs may count (iterated with
      ``.items()``, unpacked with ``**``, or passed on as an argument that is:
      ``references``, ``sequences``, ``flow.tvl1`` as ``flow_options``).

    Keys are trees: ``{key: subtree or None}``.
    """

    def __init__(self, names=(), groups=None, named=None, plain=(), whole=()):
        self.names, self.groups, self.named = frozenset(names), groups or {}, named or {}
        self.plain, self.whole = list(plain), frozenset(whole)

    def reads(self, block, name):
        """Whether the code reads ``name`` from a block called ``block`` (``None``: the
        config itself), by how it names the block (``cost``, ``cost_cfg``; ``config``)."""
        def matches(receiver):
            if block is None:
                return receiver in ("config", "cfg")
            return receiver == block or receiver.startswith(block + "_")
        return any(key == name and matches(receiver) for receiver, key in self.names)


def _key_tree(node):
    """The keys of a dict display, nested: ``{key: subtree or None}``."""
    return {key.value: (_key_tree(value) if isinstance(value, ast.Dict) else None)
            for key, value in zip(node.keys, node.values)
            if isinstance(key, ast.Constant) and isinstance(key.value, str)}


@functools.lru_cache(maxsize=16)
def code_settings(runner):
    """:class:`CodeSettings` of ``runner`` (``"module:function"``), read from the sources
    of its module and of the package modules it imports (by module, not by line: what
    another runner of the same module reads counts too). Sources are parsed, not
    imported."""
    from replication.provenance import module_closure

    module = runner.partition(":")[0]
    names, whole, passed, dicts, group_nodes = set(), set(), set(), {}, []
    for path in module_closure([module]):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
                if (node.func.attr in ("get", "pop") and node.args
                        and isinstance(node.args[0], ast.Constant)
                        and isinstance(node.args[0].value, str)):
                    names.add((_receiver(node.func.value), node.args[0].value))
                if node.func.attr in ("items", "keys", "values") and not node.args:
                    whole.add(_receiver(node.func.value))
            if isinstance(node, ast.Call):
                for keyword in node.keywords:
                    if keyword.arg is None:
                        whole.add(_receiver(keyword.value))
                    else:
                        passed.add((keyword.arg, _receiver(keyword.value)))
        for node in tree.body:
            if not (isinstance(node, ast.Assign) and isinstance(node.value, ast.Dict)):
                continue
            for target in node.targets:
                if isinstance(target, ast.Name) and target.id.endswith("GROUPS"):
                    group_nodes.append((path, node.value))
                elif isinstance(target, ast.Name) and target.id.endswith("DEFAULTS"):
                    dicts[(path.stem, target.id)] = _key_tree(node.value)
    groups = {}
    for path, node in group_nodes:   # values: NAME (this module's) or module.NAME
        for key, value in zip(node.keys, node.values):
            where = ((path.stem, value.id) if isinstance(value, ast.Name) else
                     (value.value.id, value.attr) if isinstance(value, ast.Attribute)
                     and isinstance(value.value, ast.Name) else None)
            if isinstance(key, ast.Constant) and where in dicts:
                groups[key.value] = dicts[where]
    named = {name[:-len("_DEFAULTS")].lower(): keys for (_, name), keys in dicts.items()
             if name != "DEFAULTS"}
    plain = [keys for (_, name), keys in dicts.items() if name == "DEFAULTS"]
    while True:   # passed on as an argument that is unpacked (flow_options -> options)
        more = {block for argument, block in passed if argument in whole} - whole
        if not more:
            break
        whole |= more
    return CodeSettings(names, groups, named, plain, whole - {"config", "cfg", ""})


def _receiver(node):
    """The name of the block a ``.get``/``.pop`` reads from: ``cost`` for ``cost``,
    ``config["cost"]``, ``config.get("cost")`` and ``(config.get("cost") or {})``."""
    if isinstance(node, ast.BoolOp):
        node = node.values[0]
    if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant):
        return str(node.slice.value)
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
            and node.func.attr == "get" and node.args
            and isinstance(node.args[0], ast.Constant)):
        return str(node.args[0].value)
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return ""


def _settings_block(key, config, settings):
    """Where ``key``'s parents lead in ``config``: ``(block, defaults, whole)``, the block
    (a dict, ``{}`` where the config leaves it out but the code reads it), the key trees
    of the settings the code merges it over, and whether the code takes it (or a block
    around it) whole; ``None`` when a parent is neither in the config nor a block the code
    reads, or is a value."""
    node, defaults, parent, whole = config, [], None, False
    for part in key.split(".")[:-1]:
        inner = [d[part] for d in defaults if isinstance(d.get(part), dict)]
        inner += [settings.named[part]] if part in settings.named else []
        if parent is not None and not defaults and part in settings.groups:
            inner.append(settings.groups[part])   # a block of groups, not of settings
        if isinstance(node, dict) and part in node:
            child = node[part]
            if child is not None and not isinstance(child, dict):
                return None
            node = child or {}
            inner += [d for d in settings.plain if node and set(node) <= set(d)]
        elif whole or (inner and ((parent is not None and part in settings.groups)
                                  or settings.reads(parent, part))):
            node = {}
        else:
            return None
        whole = whole or (not inner and part in settings.whole)
        defaults, parent = inner, part
    return node, defaults, whole


def may_be_read(key, config, settings):
    """Whether the dotted ``key``, which ``config`` lacks, may be a setting the code reads
    (``settings``: :func:`code_settings` of the experiment's runner): ``"defaults"`` when
    it is a key of the settings dicts its block is merged over, ``"whole"`` when the code
    takes its block whole, ``"name"`` when the code reads the name with ``.get``/``.pop``
    from a block of that name (a weaker sign: maybe for another runner of the module),
    else ``None``. ``hydra`` keys are not settings of the experiment."""
    found = None if key.split(".")[0] == "hydra" else _settings_block(key, config, settings)
    if found is None:
        return None
    leaf, (_, defaults, whole) = key.split(".")[-1], found
    if defaults:
        return "defaults" if any(leaf in d for d in defaults) else None
    if whole:
        return "whole"
    parents = key.split(".")[:-1]
    return "name" if settings.reads(parents[-1] if parents else None, leaf) else None


def _close_keys(key, config, settings=None):
    """Keys spelt like ``key`` (dotted), best first: in its block (the config's keys and
    the settings the code merges the block over; a short name also by a looser match, and
    any case), then the same name one block down (``method.tukey_c`` for
    ``method.pyramid.tukey_c``); anywhere in ``config`` when its block is neither in the
    config nor read by the code (a misspelt block)."""
    import difflib

    def dotted(node, prefix=""):
        for name, value in node.items():
            yield prefix + str(name)
            if isinstance(value, dict):
                yield from dotted(value, f"{prefix}{name}.")
    *parents, leaf = key.split(".")
    found = _settings_block(key, config or {}, settings) if settings else None
    if found is not None:
        block, defaults, _ = found
        candidates = sorted({str(c) for c in [*block, *(k for d in defaults for k in d)]}
                            - {leaf})
        lower = {c.lower(): c for c in reversed(candidates)}
        close = [lower[c] for c in difflib.get_close_matches(
            leaf.lower(), list(lower), n=3, cutoff=0.75 if len(leaf) > 3 else 0.5)]
        stem = leaf[:max(4, len(leaf) - 1)]
        close += [c for c in candidates if c.startswith(stem) and c not in close]
        if not close:   # one block down: the setting of a group
            groups = settings.groups if set(block) & set(settings.groups) else {}
            children = {c for c, v in block.items() if isinstance(v, dict)} | set(groups)
            close = [f"{child}.{leaf}" for child in sorted(children)
                     if leaf in {*(groups.get(child) or {}), *(block.get(child) or {})}]
        return [".".join(parents + [c]) for c in close[:3]]
    keys = [k for k in dotted(config or {}) if k != key and "._" not in k]
    close = difflib.get_close_matches(key, keys, n=3, cutoff=0.75)
    if close or not parents:
        return close
    # a misspelt block: its first misspelt part spelt right, then the leaf's close keys
    # there (mehtod.sigmaa -> method.sigma), else the block itself (mehtod.x -> method)
    for i, part in enumerate(parents):
        node = _get_path(config or {}, parents[:i])
        if isinstance(node, dict) and isinstance(node.get(part), dict):
            continue
        blocks = [str(k) for k, v in (node or {}).items() if isinstance(v, dict)]
        near = difflib.get_close_matches(part, blocks, n=1, cutoff=0.75)
        if not near:
            return []
        fixed = parents[:i] + near + parents[i + 1:]
        return (_close_keys(".".join(fixed + [leaf]), config, settings)
                or [".".join(parents[:i] + near)])
    return []


def _unknown_key_message(key, overrides):
    """The one line for an override of ``key``, which the experiment's config lacks."""
    where = f"Could not override '{key}'"
    if key == "hydra" or key.startswith("hydra."):
        close = _close_keys(key, {"hydra": (_experiment_config(overrides, hydra=True)
                                            or {}).get("hydra", {})})
        return (f"{where}: no such Hydra setting"
                + (f"; did you mean {' or '.join(close)}?" if close else
                   " (Hydra's settings: replicate --cfg hydra)"))
    config = _experiment_config(overrides)
    if not (config and config.get("runner")):
        return (f"{where}: no such key in the root config (configs/config.yaml); no "
                "experiment chosen: pass experiment=NAME")
    settings = code_settings(config["runner"])
    parts = key.split(".")
    for i in range(1, len(parts)):
        value = _get_path(config, parts[:i])
        if value is not None and not isinstance(value, dict):
            return (f"{where}: {'.'.join(parts[:i])} is a value ({value!r}), not a block of "
                    "settings")
    read = may_be_read(key, config, settings)
    close = _close_keys(key, config, settings)
    advice = f"add it with +{key}=VALUE"
    if read == "defaults":
        return (f"{where}: not a key of this experiment's config, but a setting the code "
                f"reads (docs/experiments.md): {advice}"
                + (f" (or did you mean {' or '.join(close)}?)" if close else ""))
    if read == "whole" and not close:
        return (f"{where}: not a key of this experiment's config, but in a block the code "
                f"takes whole (its keys are options of what it configures): {advice}")
    if read and not close:
        return (f"{where}: not a key of this experiment's config; the code reads a setting "
                f"of that name when given, maybe for another experiment (docs/experiments.md "
                f"lists this one's): if it is this one's, {advice}")
    if close:
        return (f"{where}: no such key; did you mean {' or '.join(close)}?"
                + (f" (if {key} is a setting the code reads when given, {advice})" if read
                   else ""))
    return (f"{where}: no such key in this experiment's config, nor a setting its code "
            "reads (its keys: docs/experiments.md, or replicate experiment=NAME --cfg job)")


def _get_path(config, parts):
    """``config[parts[0]][parts[1]]...``, or ``None`` where a part is missing."""
    node = config
    for part in parts:
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def _hydra_message(error, overrides=()):
    """One line from a Hydra or OmegaConf refusal (with the config's keys spelt like an
    unknown one that ``overrides`` tried to set)."""
    text = str(error)
    if text.startswith("Could not override '"):
        return _unknown_key_message(text.split("'", 2)[1], overrides)
    if text.startswith("Could not delete from config. '"):
        key = text.split("'", 2)[1]
        close = _close_keys(key, _experiment_config(overrides))
        return (f"~{key}: no such key to delete"
                + (f"; did you mean {' or '.join(close)}?" if close else ""))
    if "LexerNoViableAltException" in text:
        line = text.split("LexerNoViableAltException:", 1)[1].strip().splitlines()[0].strip()
        key, _, value = line.partition("=")
        quote = '"' if "'" in value else "'"
        spelled = ",".join(f"{quote}{part}{quote}" for part in value.split(","))
        return (f"{line}: Hydra cannot read this value unquoted (characters such as accented "
                f"letters need quotes); quote it: {key}={spelled}"
                + (" (each value of a sweep quoted on its own)" if "," in value else ""))
    if text.startswith("Ambiguous value for argument '"):
        line = text.split("\n", 1)[0].split("'", 1)[1].rsplit("'", 1)[0]
        key, _, value = line.partition("=")
        if (Path(CONFIG_DIR) / key.lstrip("+~")).is_dir():
            return (f"{line}: {key} takes one option per run; for a sweep over them: "
                    f"replicate -m {line}")
        return (f"{line}: a comma makes the value a list or, with -m, a sweep; for one "
                f"value with a comma, quote it for Hydra inside the shell's quotes: "
                f"\"{key}='{value}'\" (a list: {key}=[A,B]; a sweep: replicate -m {line})")
    if "ConfigLoader is not set" in text:
        return ("glob(...) chooses among config-group options in a sweep, not files: list "
                "the files instead (-m data.path=A.npz,B.npz)")
    if "Could not find 'experiment/" in text:
        name = text.split("Could not find 'experiment/", 1)[1].split("'", 1)[0]
        return (f"experiment={name}: unknown experiment; expected one of "
                + ", ".join(available_experiments()))
    text = text.split("\nConfig search path:", 1)[0]
    if "Available options in" in text:
        # a config group's options, one per tab-indented line: one comma-separated list
        head, _, options = text.partition("Available options in")
        group, _, names = options.partition(":")
        names = [line.strip() for line in names.splitlines() if line.strip()]
        return (" ".join(head.split()) + f"; available options in{group}: "
                + ", ".join(names))
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    lines = [line for line in lines if not line.startswith(("full_key", "object_type",
                                                            "Set the environment"))]
    return "; ".join(lines[:2]) or type(error).__name__


def unread_added_keys(overrides, defaults, settings=None):
    """The keys that ``+KEY=VALUE`` (or ``++KEY=VALUE``) overrides add, as given
    (``+KEY``, ``++KEY``), which neither the experiment's config (``defaults``) holds nor
    the code may read (:func:`may_be_read` with ``settings``, by default
    :func:`code_settings` of the config's runner): Hydra
    accepts any new key, and a runner ignores what it does not read, so a misspelt
    ``+budgett=300`` would change nothing. Config groups (``+smoke=``) and ``hydra`` keys
    are left out."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    unread = []
    for override in OverridesParser.create().parse_overrides(list(overrides)):
        key = override.key_or_group
        if (not (override.is_add() or override.is_force_add())
                or key == "hydra" or key.startswith(("hydra.", "hydra/"))
                or (Path(CONFIG_DIR) / key).is_dir()):
            continue
        *parents, leaf = key.split(".")
        block = _get_path(defaults, parents)
        if isinstance(block, dict) and leaf in block:
            continue
        if settings is None:   # parsed only when an added key is not in the config
            settings = (code_settings(defaults["runner"]) if defaults.get("runner")
                        else CodeSettings())
        if not may_be_read(key, defaults, settings):
            unread.append(("++" if override.is_force_add() else "+") + key)
    return unread


def _note_unread(overrides, defaults, name):
    for key in unread_added_keys(overrides, defaults or {}):
        print(f"note: {key} is not a key of {name}'s config, nor a setting the code "
              "reads: the run ignores it, or refuses it where it checks its settings "
              "(check the spelling against docs/experiments.md)", file=sys.stderr)


def precheck(overrides):
    """Compose the config of a single run as Hydra will and check it (:func:`check_config`,
    ``out``) before Hydra creates any folder. Returns the output folder."""
    with composing(overrides) as compose:
        cfg = compose(config_name="config", overrides=list(overrides))
        config = OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)
        name = config.get("name")
        defaults = (_own_config(compose, name) if name in available_experiments()
                    else None)
    if not config.get("runner"):
        raise InputError("no experiment chosen: pass experiment=NAME, one of "
                         + ", ".join(available_experiments()))
    out, key = config.get("out"), "out"
    if out is None:  # Hydra's run folder (configs/config.yaml: out, else results/NAME)
        from hydra.core.override_parser.overrides_parser import OverridesParser

        run_dir = [str(o.value()) for o in OverridesParser.create().parse_overrides(
            list(overrides)) if o.key_or_group == "hydra.run.dir"]
        out, key = (run_dir[-1], "hydra.run.dir") if run_dir else (
            f"results/{config['name']}", "out")
    check_config(config, defaults)
    _note_unread(overrides, defaults, config["name"])
    check_out(out, force=config.get("force", False), key=key)
    check_writable(out, key=key)
    return out


NAME_BYTES = 255   # the longest file or folder name most file systems take


def _fixed_output(override):
    """Whether ``override`` sets an output folder or file (``out``, :data:`OUTPUT_KEYS`,
    :data:`OUTPUT_FILE_KEYS`) to one value for every job of a sweep: not swept, not made
    per job with ``${...}``, not null or empty."""
    key = override.get_key_element().lstrip("+~")
    if (key not in ("out",) + OUTPUT_KEYS + OUTPUT_FILE_KEYS or override.is_sweep_override()
            or override.is_delete() or "=" not in override.input_line):
        return False
    value = override.input_line.split("=", 1)[1].strip()
    return "${" not in value and value not in ("", "null")


def _check_sweep_settings(hydra_config, launcher, longest):
    """Refusals of a sweep's ``hydra`` settings before any job: an empty
    ``hydra.sweep.dir`` (the job folders would go into the working directory), joblib's
    ``n_jobs=0`` (joblib's traceback), and a job folder name longer than the file system
    takes (``longest``: the job with each swept key at its longest value)."""
    from hydra._internal.config_loader_impl import get_overrides_dirname
    from hydra.core.override_parser.overrides_parser import OverridesParser

    check(str(hydra_config.sweep.dir).strip() != "",
          "hydra.sweep.dir=: empty; expected a folder (the default is multirun/NAME)")
    target = str(OmegaConf.select(hydra_config, "launcher._target_", default=""))
    n_jobs = OmegaConf.select(hydra_config, "launcher.n_jobs", default=None)
    check(not (target.endswith("JoblibLauncher") and n_jobs == 0),
          "hydra.launcher.n_jobs=0: expected a number of processes >= 1 (or -1: one per CPU)")
    if any(line.split("=", 1)[0].lstrip("+") == "hydra.sweep.subdir" for line in launcher):
        return
    dirname = hydra_config.job.config.override_dirname
    name = folder_name(get_overrides_dirname(OverridesParser.create().parse_overrides(longest),
                                             list(dirname.exclude_keys), dirname.item_sep,
                                             dirname.kv_sep))
    size = len(name.encode())
    check(size <= NAME_BYTES,
          f"a job folder of this sweep would be named with {size} bytes (its overrides, "
          f"{name[:60]}...), more than file systems take ({NAME_BYTES}); shorten the values "
          "(a data folder, not long file paths) or name job folders by number: "
          "hydra.sweep.subdir='${hydra.job.num}' (replicate-gather still reads each job's "
          "overrides from its result.json)")


def compose_first_job(args):
    """Compose the jobs of a sweep that differ from the first in one swept value (each
    value of each swept key once) and check them (:func:`check_config`), so that Hydra's
    refusals and bad values come as one :class:`InputError` line before any job runs or
    Hydra writes anything: the first job with the ``hydra`` overrides (a launcher or one
    of its keys misspelt, :func:`_check_sweep_settings`), in a sweep over experiments the
    keys set for all of them against the root config (Hydra applies them to it first), and
    a fixed ``out``, ``figure_dir``, ... (every job would write there).

    Returns ``(folders, record)``: the sweep folders of the jobs (``hydra.sweep.dir`` as
    composed here; in a sweep over experiments, one per experiment) and the folder Hydra
    writes the sweep's ``multirun.yaml`` to (composed without the swept experiment: in
    ``multirun/${name}``, ``multirun/None``; :func:`_place_sweep_record` moves it).

    Parameters
    ----------
    args : list of str
        The sweep's overrides, without ``-m``.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    try:
        overrides, swept, launcher, plain, fixed, longest = [], [], [], [], [], []
        unswept = []   # what Hydra's sweeper composes its own config with
        for override in OverridesParser.create().parse_overrides(list(args)):
            if override.key_or_group.startswith("hydra"):
                launcher.append(override.input_line)
                continue
            key = override.get_key_element()
            if _fixed_output(override):
                fixed.append(override.input_line)
            if override.is_sweep_override():
                values = list(override.sweep_string_iterator())
                overrides.append(f"{key}={values[0]}" if values else override.input_line)
                swept.extend((len(overrides) - 1, f"{key}={value}") for value in values[1:])
                longest.append(f"{key}={max(values, key=lambda v: len(folder_name(v)))}"
                               if values else override.input_line)
            else:
                overrides.append(override.input_line)
                unswept.append(override.input_line)
                longest.append(override.input_line)
                if not (override.is_add() or override.is_force_add()
                        or (Path(CONFIG_DIR) / override.key_or_group).is_dir()):
                    plain.append(override.key_or_group)
        jobs = [overrides] + [overrides[:i] + [line] + overrides[i + 1:] for i, line in swept]
        # one folder for every job: only the last job's result would stay; shared figure
        # and data folders (tests and users keep figures out of figures/ that way) only lose
        # the earlier jobs' figures: noted
        if len(jobs) > 1:
            for line in fixed:
                key = line.split("=", 1)[0].lstrip("+~")
                if key == "out":
                    raise InputError(
                        f"{line} in a sweep: every job would write that folder and only the "
                        "last result would stay; leave out unset (each job writes "
                        "multirun/NAME/OVERRIDES, or hydra.sweep.dir=DIR/OVERRIDES), sweep "
                        "it (out=A,B) or make it per job (out=DIR/${seed})")
                per_job = (f"{key}=DIR/${{seed}}/{Path(line.split('=', 1)[1]).name}"
                           if key in OUTPUT_FILE_KEYS else f"{key}=DIR/${{seed}}")
                print(f"note: {line} in a sweep: every job writes there, so only the last "
                      f"job's files stay (each result.json is kept); {per_job} or leaving "
                      f"{key} unset keeps them per job", file=sys.stderr)
        with composing(args) as compose:
            hydra_config = compose(config_name="config", overrides=overrides + launcher,
                                   return_hydra_config=True).hydra
            _check_sweep_settings(hydra_config, launcher, longest)
            sweep_dir = str(hydra_config.sweep.dir)
            _check_shared_folders(compose, hydra_config, sweep_dir, swept, jobs, launcher)
            folders, record = [sweep_dir], sweep_dir
            if any(line.startswith("experiment=") for _, line in swept):
                _check_shared_keys(plain, compose(config_name="config"))
                folders = list(dict.fromkeys(
                    str(compose(config_name="config", overrides=job + launcher,
                                return_hydra_config=True).hydra.sweep.dir) for job in jobs))
                record = str(compose(config_name="config", overrides=unswept + launcher,
                                     return_hydra_config=True).hydra.sweep.dir)
            owns, own = {}, None
            for job in jobs:
                config = OmegaConf.to_container(compose(config_name="config", overrides=job),
                                                resolve=True)
                name = config.get("name")
                if name in available_experiments():
                    if name not in owns:
                        owns[name] = _own_config(compose, name)
                    own = owns[name]
                if config.get("runner"):
                    check_config(config, own)
        for name, own in owns.items():   # each experiment of the sweep reads its own keys
            _note_unread(overrides, own, name)
    except InputError:
        raise
    except (HydraException, ValueError) as error:   # the override parser's refusals
        raise InputError(_hydra_message(error, list(args))) from None
    return folders, record


def _place_sweep_record(folders, record, task):
    """After a sweep over experiments, put the ``multirun.yaml`` Hydra wrote to ``record``
    (``multirun/None``: the sweep's own config names no experiment) into each experiment's
    sweep folder that exists, where ``replicate-gather`` reads it (which jobs the sweep
    made), and remove ``record`` when that leaves it empty. Only when the file is this
    sweep's (its task overrides are ``task``): a sweep over experiments started since
    writes the same file and moves its own. A failure is a warning: the sweep's own
    outcome (its status, Ctrl-C's clean-up) comes first."""
    source = Path(record) / "multirun.yaml"
    if record in folders or not source.is_file():
        return
    try:
        if list(OmegaConf.load(source).hydra.overrides.task) != list(task):
            return
        for folder in map(Path, folders):
            if folder.is_dir():
                shutil.copyfile(source, folder / "multirun.yaml")
        source.unlink()
    except Exception as error:  # noqa: BLE001  (a disk error, a file not Hydra's)
        print(f"warning: {source}: not moved into the experiments' sweep folders ({error}); "
              "replicate-gather cannot tell missing jobs there", file=sys.stderr)
        return
    _remove_empty([record])


def _check_shared_folders(compose, hydra_config, sweep_dir, swept, jobs, launcher):
    """Refuse a sweep over a key that job folder names leave out (``experiment``,
    ``progress``, the limits: ``hydra.job.config.override_dirname.exclude_keys``) when two
    of its jobs would write one folder: the same sweep folder (and so the same job
    folders), or, where ``out`` is set per job (``out=DIR/${seed}``), the same ``out``;
    only the last result would stay. ``experiment=a,b`` is safe in the default
    ``multirun/${name}`` (a folder per experiment), not in one ``hydra.sweep.dir``."""
    if any(line.split("=", 1)[0].lstrip("+") == "hydra.sweep.subdir" for line in launcher):
        return
    per_job_out = any(line.split("=", 1)[0].lstrip("+~") == "out" for line in jobs[0])
    excluded = set(hydra_config.job.config.override_dirname.exclude_keys)

    def folder(job):
        composed = compose(config_name="config", overrides=job + launcher,
                           return_hydra_config=per_job_out is False)
        return str(composed.out if per_job_out else composed.hydra.sweep.dir)
    first = None
    for (index, line), job in zip(swept, jobs[1:]):
        key = line.split("=", 1)[0].lstrip("+~")
        if key not in excluded or key == "out":
            continue
        first = folder(jobs[0]) if first is None else first
        if folder(job) != first:
            continue
        fix = "${name}" if key == "experiment" else f"${{{key}}}"
        where = (f"out={first} for both" if per_job_out else
                 f"one folder ({sweep_dir}): job folders are named by the other overrides, "
                 f"{key} left out, so both would write the same job folders")
        raise InputError(
            f"{key} swept into {where}: {jobs[0][index]} and {line} would overwrite each "
            "other and only the last result would stay; "
            + (f"make out depend on it (out=DIR/{fix}/...)" if per_job_out else
               f"sweep into a folder per value (the default multirun/${{name}}, or "
               f"hydra.sweep.dir=DIR/{fix}), or name job folders by number: "
               "hydra.sweep.subdir='${hydra.job.num}'"))


def _check_shared_keys(keys, root):
    """Refuse, in a sweep over experiments, a key (not swept) the root config
    (``configs/config.yaml``) lacks: Hydra applies the sweep's other overrides to it
    before any experiment."""
    root = OmegaConf.to_container(root)
    for key in keys:
        node = root
        for part in key.split("."):
            if isinstance(node, list) and part.isdigit() and int(part) < len(node):
                node = node[int(part)]
                continue
            if not (isinstance(node, dict) and part in node):
                raise InputError(
                    f"{key}: a sweep over experiments can set only the keys every "
                    "experiment shares (configs/config.yaml: seed, out, resume, strict, "
                    "data.path, limits...); sweep each experiment on its own to set it")
            node = node[part]


def _missing_chain(path):
    """The folders of ``path`` that do not exist yet, deepest first."""
    chain, path = [], Path(path).absolute()
    while not path.exists() and path.parent != path:
        chain.append(path)
        path = path.parent
    return chain


def _remove_empty(chain):
    """Remove the folders of ``chain`` (deepest first) while they are empty; those already
    gone are passed over."""
    for folder in map(Path, chain):
        try:
            folder.rmdir()
        except FileNotFoundError:
            continue
        except OSError:
            return


def flag_overrides(args):
    """``args`` with the options that stand for config overrides replaced by them:
    ``--strict`` (``strict=true``), ``--quiet`` (``progress=none``) and
    ``--progress=MODE`` or ``--progress MODE`` (``progress=MODE``)."""
    replaced, args = [], list(args)
    while args:
        arg = args.pop(0)
        if arg == "--strict":
            replaced.append("strict=true")
        elif arg == "--quiet":
            replaced.append("progress=none")
        elif arg.startswith("--progress="):
            replaced.append("progress=" + arg.split("=", 1)[1])
        elif arg == "--progress" and args and not args[0].startswith("-") and (
                "=" not in args[0]):
            replaced.append("progress=" + args.pop(0))
        else:
            replaced.append(arg)
    return replaced


def _hydra_parser():
    """Hydra's argument parser, raising :class:`ValueError` with argparse's one-line message
    where argparse would print its whole usage and exit."""
    from hydra._internal.utils import get_args_parser

    parser = get_args_parser()
    parser.exit_on_error = False

    def refuse(message):
        raise ValueError(message)
    parser.error = refuse
    return parser


def expand_abbreviations(args, parser):
    """``args`` with each abbreviation of one of Hydra's long options (``--mult``, which
    argparse takes for ``--multirun``; ``parser``: :func:`_hydra_parser`) spelt out, so
    that a sweep is seen as one."""
    options = [option for action in parser._actions for option in action.option_strings
               if option.startswith("--")]
    expanded = []
    for arg in args:
        name, equals, value = arg.partition("=")
        matches = [option for option in options if option.startswith(name)]
        if (name.startswith("--") and len(name) > 2 and name not in options
                and len(matches) == 1):
            arg = matches[0] + equals + value
        expanded.append(arg)
    return expanded


def unknown_options(args, parser):
    """``(known, message)``: Hydra's parse of ``args`` (``parser``: :func:`_hydra_parser`;
    ``None`` when it fails) and one line naming the options that neither the suite nor
    Hydra knows, or that Hydra's argparse refuses (a bad value, an ambiguous
    abbreviation), where argparse would print its whole usage; ``message`` is ``None``
    when all are known."""
    import argparse
    import difflib

    tail = ("; replicate takes --strict, --quiet, --progress=MODE, Hydra's options "
            "(replicate --help) and KEY=VALUE overrides")
    if "--progress" in args:   # flag_overrides took every --progress followed by a value
        return None, "--progress needs a value: --progress=bar|plain|none" + tail
    try:
        known_args, unknown = parser.parse_known_args(args)
    except (argparse.ArgumentError, ValueError) as error:
        return None, f"{error}" + tail
    modes = [name for name, on in (
        ("--run", known_args.run), ("--multirun", known_args.multirun),
        ("--cfg", known_args.cfg), ("--info", known_args.info),
        ("--shell-completion", known_args.shell_completion)) if on]
    if len(modes) > 1:
        return known_args, f"{' and '.join(modes)}: Hydra takes one of them at a time" + tail
    for option, value in (("--package", known_args.package),
                          ("--config-path", known_args.config_path),
                          ("--config-name", known_args.config_name),
                          ("--config-dir", known_args.config_dir)):
        if value is not None and "=" in value:
            return known_args, (f"{option} took {value} as its value (it needs one of its "
                                f"own: {option} VALUE, or {option}=VALUE)" + tail)
    refused = _refused_option_value(known_args)
    if refused:
        return known_args, refused
    if not unknown:
        return known_args, None
    stray = [arg for arg in unknown if not arg.startswith("-")]
    unknown = [arg for arg in unknown if arg.startswith("-")]
    if stray and not unknown:   # argparse takes one run of overrides (a=1 -m b=2)
        return known_args, (
            f"{' '.join(stray)}: overrides split by one of Hydra's options; give them "
            "together, before or after the options (replicate -m KEY=VALUE ..., "
            "replicate KEY=VALUE ... --cfg job; --strict and --quiet count as overrides)")
    known = ["--strict", "--quiet", "--progress"] + [
        option for action in parser._actions for option in action.option_strings]
    hints = []
    for arg in unknown:
        close = difflib.get_close_matches(arg.split("=", 1)[0], known, n=1, cutoff=0.75)
        if close:
            hints.append(f"{arg}: did you mean {close[0]}?")
    return known_args, (f"unknown option(s) {' '.join(unknown)}"
                        + (f" ({'; '.join(hints)})" if hints else "") + tail)


def _refused_option_value(known):
    """One line for a value of Hydra's options that Hydra would refuse with several lines
    or a traceback (a missing config, folder or file; shell completion without its
    command), else ``None``. ``known``: Hydra's parse of the command line."""
    if known.shell_completion and not any(
            o.split("=", 1)[0] in ("install", "uninstall", "query") for o in known.overrides):
        return ("--shell-completion needs one of install=SHELL, uninstall=SHELL or "
                "query=SHELL (e.g. replicate --shell-completion install=bash)")
    for option, value in (("--config-dir", known.config_dir),
                          ("--config-path", known.config_path)):
        # a relative --config-path is Hydra's to resolve (beside the entry point's file)
        if value is not None and (option == "--config-dir" or Path(value).is_absolute()) \
                and not Path(value).is_dir():
            return f"{option}={value}: no such folder"
    if (known.config_name is not None and known.config_dir is None
            and known.config_path is None
            and not (Path(CONFIG_DIR) / known.config_name).with_suffix(".yaml").is_file()):
        names = sorted(path.stem for path in Path(CONFIG_DIR).glob("*.yaml"))
        return (f"--config-name={known.config_name}: no such config in {CONFIG_DIR} "
                f"(there: {', '.join(names)}; experiments are chosen with experiment=NAME)")
    rerun = known.experimental_rerun
    if rerun is not None and not Path(rerun).is_file():
        return (f"--experimental-rerun {rerun}: no such file (Hydra reruns from a run's "
                ".hydra/config.pickle, which runs write with hydra.output_subdir=.hydra)")
    return None


USAGE = """usage: replicate experiment=NAME [key=value ...] [--strict] [--quiet]
                 [--progress=bar|plain|none]
       replicate -m experiment=NAME key=v1,v2 ...   (a sweep: multirun/NAME/OVERRIDES)

The suite's options (each stands for a config key):
  --strict           strict=true: a warning refuses the run (status 2)
  --quiet            progress=none: no progress lines or bars
  --progress=MODE    progress=MODE (auto: a bar on a terminal, else plain lines)
Experiments and their keys: docs/experiments.md; the command line, exit statuses and
result.json: docs/results.md. Hydra's own help follows.
"""


def main():
    """Console-script entry point."""
    parser = _hydra_parser()
    sys.argv = sys.argv[:1] + expand_abbreviations(flag_overrides(sys.argv[1:]), parser)
    if {"--help", "-h"} & set(sys.argv[1:]):
        print(USAGE)
    args = sys.argv[1:]
    known, unknown = unknown_options(args, parser)
    if unknown:
        _error(unknown)

    chain, sweep_dir, folders = [], None, []
    # SIGTERM raises Interrupted like Ctrl-C; one that lands in an import is not lost
    with interruptible(terminate=True):
        try:
            flags = [arg for arg in args if arg.startswith("-")]
            inspect = _inspecting(known)
            if inspect is not None:
                # --cfg, --info, --resolve, --package: Hydra's refusals as one line too
                try:
                    _compose_check(inspect)
                except InputError as error:
                    _error(error)
            elif flags and set(flags) <= {"-m", "--multirun"}:
                # a sweep: Hydra's refusals (unknown key or experiment) as one line; each job
                # checks its own config
                try:
                    folders, sweep_dir = compose_first_job([arg for arg in args
                                                            if arg not in flags])
                except InputError as error:
                    _error(error)
                chain = _start_sweep(sweep_dir)
            if set(flags) <= {"-r", "--run"}:
                # a single run: refuse bad config before Hydra creates the run folder
                try:
                    out = precheck([arg for arg in args if arg not in flags])
                except InputError as error:
                    _error(error)
                except OSError as error:
                    _error(_os_message(error))
                chain = _missing_chain(out)
            try:
                _hydra_main()
            except SystemExit as done:
                if done.code not in (0, None):
                    _remove_empty(chain)
                raise
            finally:
                if sweep_dir is not None:
                    _place_sweep_record(folders, sweep_dir,
                                        [arg for arg in args if not arg.startswith("-")
                                         and not arg.lstrip("+~").startswith("hydra")])
            if sweep_dir is not None:
                _report_refused(chain)
        except KeyboardInterrupt:
            for folder in folders:
                _drop_partial_jobs(folder)
            _remove_empty(chain)
            _interrupted(sweep=sweep_dir is not None)
        finally:
            os.environ.pop(SWEEP_ENVIRONMENT, None)


def _inspecting(known):
    """The overrides of the command line (``known``: Hydra's parse of it) when they ask
    Hydra to show something rather than run (``--cfg``, ``--info``, ``--resolve``,
    ``--package``), else ``None`` (also for help and shell completion, which read no
    experiment)."""
    if known.help or known.hydra_help or known.shell_completion:
        return None
    if known.cfg or known.info or known.resolve or known.package:
        return list(known.overrides)
    return None


def _compose_check(overrides):
    """Compose ``overrides`` as Hydra will; :class:`InputError` with Hydra's refusal as one
    line (:func:`_hydra_message`)."""
    with composing(overrides) as compose:
        compose(config_name="config", overrides=list(overrides))


def _start_sweep(sweep_dir):
    """Name this sweep for its jobs (:data:`SWEEP_ENVIRONMENT`, which the launchers'
    worker processes inherit): an id, in its staging folders' names, and a folder of
    refusals of its own (absolute, next to ``sweep_dir``), so that two sweeps into one
    folder keep their refusals and clean-ups apart. Returns the folders of the refusals'
    path that do not exist yet, deepest first (removed when empty after the sweep)."""
    import json
    import uuid

    sweep_id = uuid.uuid4().hex[:8]
    folder = Path(sweep_dir).absolute() / f".refused-{sweep_id}"
    os.environ[SWEEP_ENVIRONMENT] = json.dumps({"id": sweep_id, "refused": str(folder)})
    return _missing_chain(folder)

def _report_refused(chain):
    """After a sweep, the jobs a launcher's workers refused (:func:`_refuse`): one
    ``error:`` line and status 2, as a refused run ends. ``chain``: the folders
    :func:`_start_sweep` gave, removed when empty."""
    refused = _refused_jobs(_sweep().get("refused", chain[0] if chain else "."))
    _remove_empty(chain)
    if refused:
        first = refused[0]
        more = f" (and {len(refused) - 1} more job(s), their error: lines above or in the " \
               "launcher's logs)" if len(refused) > 1 else ""
        _error(f"{len(refused)} job(s) of the sweep refused (any other job ran and kept its "
               f"result): job {first['job']} ({first['overrides']}): {first['message']}{more}"
               "; after fixing, the same sweep with resume=true runs only what is missing")


def _drop_partial_jobs(sweep_dir):
    """After Ctrl-C in a sweep, remove this sweep's staging folders (named with its id,
    :func:`_start_sweep`: a launcher's workers can be killed before their own clean-up
    runs) and the job folders they leave empty; finished jobs and other sweeps' folders
    stay."""
    sweep_id = _sweep().get("id")
    root = Path(sweep_dir)
    if not sweep_id or not root.is_dir():
        return
    for path in root.glob(f".*.partial-{sweep_id}*"):
        shutil.rmtree(path, ignore_errors=True)
        job = root / path.name[1:].rsplit(f".partial-{sweep_id}", 1)[0]
        _remove_empty([job])

if __name__ == "__main__":
    main()
