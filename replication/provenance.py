"""Hashes that tie a result to the config and code that made it.

The code hash of an experiment covers only the modules of this package that its runner
imports, directly or through other modules of the package (found statically, from the
source), the modules that write every result (:data:`CORE_MODULES`) and the pinned
requirements: a change to the cloth code does not invalidate a motion result. Within the
runner's own module, only the definitions its function reaches count, so a change to
another runner's figure leaves it current. Code counts by what it does, statement by
statement, not by where it lives: a pure move changes no hash (:func:`code_text`).
"""

from __future__ import annotations

import ast
import copy
import hashlib
import json
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
PROJECT_ROOT = PACKAGE_DIR.parent
PACKAGE = PACKAGE_DIR.name

# every result.json is written through these
CORE_MODULES = ("replication.cli", "replication.provenance", "replication.results")


# config keys that do not change a result: where it goes, whether to resume, how the
# report shows it, the tests' small settings, the default metrics of sweep plots, whether
# warnings refuse the run, whether results/ may be overwritten, the size/time limits and
# how progress shows
NOT_RESULT_KEYS = ("out", "resume", "report", "smoke", "sweep_metrics", "strict", "force",
                   "limits", "progress")


def config_hash(config):
    """sha256 of a resolved config without :data:`NOT_RESULT_KEYS`, independent of key
    order."""
    config = {key: value for key, value in config.items() if key not in NOT_RESULT_KEYS}
    text = json.dumps(config, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def module_file(name):
    """Source file of module ``name`` of this package, or ``None`` when there is none."""
    parts = name.split(".")
    if parts[0] != PACKAGE:
        return None
    base = PROJECT_ROOT.joinpath(*parts)
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def imported_modules(path, name):
    """Names of this package's modules imported by the source file ``path`` (module
    ``name``): ``import a.b``, ``from a import b`` (``a.b`` when it is a module) and
    relative imports."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level:
                anchor = name.split(".")
                anchor = anchor[:len(anchor) - node.level + (1 if is_package else 0)]
                module = ".".join(anchor + ([module] if module else []))
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names)
    return {module for module in found if module_file(module) is not None}


MOVES_RECORD = PROJECT_ROOT / "results" / "provenance-moves.json"


def _moves():
    """``{runner: {"legacy_runner", "legacy_code_sha256", "code_sha256"}}`` of
    :data:`MOVES_RECORD` (:mod:`replication.moves`), ``{}`` without one."""
    try:
        return json.loads(MOVES_RECORD.read_text())["runners"]
    except FileNotFoundError:
        return {}


def accepted_code_hashes(runner):
    """The ``code_sha256`` values of results made by the current code of ``runner``: its
    hash, and the earlier scheme's hash of code that has only moved since
    (:mod:`replication.moves`) and not changed after. Compute once, test many runs."""
    now = code_hash(runner)
    moved = _moves().get(runner)
    if moved and moved["code_sha256"] == now:
        return {now, moved["legacy_code_sha256"]}
    return {now}


def legacy_runner(runner):
    """The name ``runner`` had before a recorded move (``None`` if none)."""
    return _moves().get(runner, {}).get("legacy_runner")


def module_closure(roots):
    """Sorted source files of modules ``roots`` and of every module of this package they
    import, transitively, with the ``__init__.py`` of each package on the way."""
    seen, todo = set(), list(roots)
    while todo:
        name = todo.pop()
        if name in seen or module_file(name) is None:
            continue
        seen.add(name)
        parts = name.split(".")
        todo.extend(".".join(parts[:i]) for i in range(1, len(parts)))
        todo.extend(imported_modules(module_file(name), name))
    return sorted({module_file(name) for name in seen})


class _CodeOnly(ast.NodeTransformer):
    """Drops import statements and docstrings from a syntax tree."""

    def generic_visit(self, node):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr) \
                and isinstance(body[0].value, ast.Constant) \
                and isinstance(body[0].value.value, str):
            node.body = body[1:]
        return super().generic_visit(node)

    def visit_Import(self, node):
        return None

    visit_ImportFrom = visit_Import


def code_text(node):
    """What a syntax tree does, as text: its structure without import statements,
    docstrings, comments, layout or line numbers. Which code a result uses is the
    closure's business (:func:`module_closure`), what that code does is this text's, so a
    move that only rewrites imports and the paths named in docstrings leaves it alone."""
    return ast.dump(_CodeOnly().visit(copy.deepcopy(node)), include_attributes=False)


_DIGESTS = {}   # sha256 of a file's bytes -> digests: replicate-all hashes ~30 runners at once


def source_digests(path):
    """sha256 of the :func:`code_text` of each top-level statement of a source file
    (``__all__``, which only names, left out). Statements, not files: a definition moved
    from one module to another, or a module split in two, is the same code."""
    source = Path(path).read_bytes()
    key = hashlib.sha256(source).hexdigest()
    if key not in _DIGESTS:
        # parsed afresh, so stripped in place (code_text would copy every statement)
        tree = _CodeOnly().visit(ast.parse(source, filename=str(path)))
        _DIGESTS[key] = [
            hashlib.sha256(ast.dump(node, include_attributes=False).encode()).hexdigest()
            for node in tree.body if not _is_all(node)]
    return _DIGESTS[key]


def _is_all(node):
    """Whether a top-level statement is the ``__all__`` list (it only names)."""
    targets = node.targets if isinstance(node, ast.Assign) else []
    return any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets)


def _bindings(tree):
    """Top-level definitions of a module (``{name: node}``) and the package modules its
    top-level imports bind to names (``{name: module}``)."""
    defs, imported = {}, {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            defs[node.name] = node
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            defs.update((leaf.id, node) for target in targets for leaf in ast.walk(target)
                        if isinstance(leaf, ast.Name))
        elif isinstance(node, ast.Import):
            imported.update((alias.asname or alias.name.partition(".")[0], alias.name)
                            for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level:
            imported.update((alias.asname or alias.name, _target(node.module, alias.name))
                            for alias in node.names)
    return defs, imported


def _target(module, name):
    """``module.name`` when that is a module of the package, else ``module``."""
    full = f"{module}.{name}"
    return full if module_file(full) is not None else module


def runner_parts(runner):
    """What the function of a runner ``"module:function"`` reaches in its own module.

    Returns the :func:`code_text` of the top-level definitions it uses, transitively, and
    the package modules those use. Another runner's figure in the same module is
    then no part of this runner's code, and a change to it leaves this runner's results
    current.
    """
    module, _, function = runner.partition(":")
    path = module_file(module)
    source = path.read_text()
    tree = ast.parse(source, filename=str(path))
    defs, imported = _bindings(tree)
    if function not in defs:
        raise ValueError(f"runner {runner!r}: {path} has no top-level {function!r}")
    seen, todo, modules = set(), [function], set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        for node in ast.walk(defs[name]):
            if isinstance(node, ast.Name):
                if node.id in defs:
                    todo.append(node.id)
                elif node.id in imported:
                    modules.add(imported[node.id])
            elif isinstance(node, ast.ImportFrom) and not node.level:
                modules.update(_target(node.module, alias.name) for alias in node.names)
            elif isinstance(node, ast.Import):
                modules.update(alias.name for alias in node.names)
    nodes = {id(defs[name]): defs[name] for name in seen}.values()
    segments = sorted(code_text(node) for node in nodes)
    return segments, sorted(m for m in modules if module_file(m) is not None)


def code_hash(runner=None):
    """sha256 over the Python sources behind a result and the pinned requirements.

    ``runner``: ``"module:function"``: the definitions that function reaches in its module
    and every package module those import (:func:`runner_parts`, :func:`module_closure`);
    a module name: that module's closure; ``None``: the whole package. Both with
    :data:`CORE_MODULES`. Each distinct top-level statement counts once by its
    :func:`code_text`, in no order of files or paths (:func:`source_digests`; docs/results.md,
    "Provenance and moves"): a pure move of code between modules changes no hash.
    """
    segments = []
    if runner is None:
        files = sorted(PACKAGE_DIR.rglob("*.py"))
    else:
        module, _, function = runner.partition(":")
        roots = [module]
        if function:
            segments, roots = runner_parts(runner)
            parts = module.split(".")
            roots = roots + [".".join(parts[:i]) for i in range(1, len(parts))]
        files = module_closure([*roots, *CORE_MODULES])
    # a set: a statement is the same code wherever it lives
    digests = sorted({digest for path in files for digest in source_digests(path)})
    lock = PROJECT_ROOT / "requirements.lock"
    if lock.exists():
        digests.append(file_sha256(lock))
    digest = hashlib.sha256()
    for item in digests + segments:
        digest.update(item.encode())
    return digest.hexdigest()


def file_sha256(path):
    """sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


# config keys naming other files and folders a run reads: a gathered sweep, the sequences
# of a data experiment, the result folder of another experiment
INPUT_KEYS = ("data_file", "sequences_dir", "single_result", "table_result")


def input_paths(config):
    """The data files and folders a run reads, as its config names them: ``data.path``,
    else ``default_data``; the files of ``references``; and :data:`INPUT_KEYS`. Together
    they hold all a run reads of the experiments it depends on, so that a dependency
    re-run with the same outputs leaves it current (``replicate-all``)."""
    data = config.get("data") if isinstance(config.get("data"), dict) else {}
    paths = [data.get("path") or config.get("default_data")]
    references = config.get("references")
    if isinstance(references, dict):
        paths.extend(references.values())
    paths.extend(config.get(key) for key in INPUT_KEYS)
    return [str(p) for p in paths if isinstance(p, str) and p]


def path_sha256(path):
    """sha256 of a file's bytes, or over the relative names and bytes of every file below
    a folder; ``None`` when the path does not exist (yet)."""
    path = Path(path)
    if path.is_file():
        return file_sha256(path)
    if not path.is_dir():
        return None
    digest = hashlib.sha256()
    for item in sorted(p for p in path.rglob("*") if p.is_file()):
        digest.update(str(item.relative_to(path)).encode())
        digest.update(file_sha256(item).encode())
    return digest.hexdigest()


def inputs_hash(config):
    """``{path: sha256}`` of the run's input files and folders (:func:`input_paths`)."""
    return {path: path_sha256(path) for path in input_paths(config)}


def run_provenance(config):
    """The ``provenance`` of a run: config, code and input hashes."""
    return {"config_sha256": config_hash(config), "code_sha256": code_hash(config["runner"]),
            "inputs_sha256": inputs_hash(config)}
