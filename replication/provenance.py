"""Hashes that tie a result to the config and code that made it.

The code hash of an experiment covers only the modules of this package that its runner
imports, directly or through other modules of the package (found statically, from the
source), the modules that write every result (:data:`CORE_MODULES`) and the pinned
requirements: a change to the cloth code does not invalidate a motion result.
"""

from __future__ import annotations

import ast
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


def _imported_modules(path, name):
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
        todo.extend(_imported_modules(module_file(name), name))
    return sorted({module_file(name) for name in seen})


def code_hash(runner=None):
    """sha256 over the Python sources behind a result and the pinned requirements.

    ``runner`` : ``"module:function"`` (or a module name): hash the modules it imports
    (:func:`module_closure`) and :data:`CORE_MODULES`; ``None``: the whole package.
    """
    if runner is None:
        files = sorted(PACKAGE_DIR.rglob("*.py"))
    else:
        files = module_closure([runner.partition(":")[0], *CORE_MODULES])
    lock = PROJECT_ROOT / "requirements.lock"
    if lock.exists():
        files.append(lock)
    digest = hashlib.sha256()
    for path in files:
        digest.update(str(path.relative_to(PROJECT_ROOT)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def file_sha256(path):
    """sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def input_paths(config):
    """The data files and folders a run reads, as its config names them: ``data.path``,
    else ``default_data``, and the files of ``references`` and ``data_file``."""
    data = config.get("data") if isinstance(config.get("data"), dict) else {}
    paths = [data.get("path") or config.get("default_data")]
    references = config.get("references")
    if isinstance(references, dict):
        paths.extend(references.values())
    paths.append(config.get("data_file"))
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
