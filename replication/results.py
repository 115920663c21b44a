"""Writing and reading ``result.json`` (docs/results.md)."""

from __future__ import annotations

import json
import math
import os
import platform
import tempfile
from importlib import metadata
from pathlib import Path

import numpy as np

from replication.errors import InputError

TRACKED_PACKAGES = (
    "numpy", "scipy", "scikit-image", "matplotlib", "pymoo", "hydra-core", "numba",
)


def package_versions():
    """Versions of the packages whose behaviour the results depend on."""
    versions = {"python": platform.python_version()}
    for name in TRACKED_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def to_jsonable(value):
    """Numpy scalars and arrays to plain JSON types; non-finite floats to strings."""
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        value = float(value)
        if math.isfinite(value):
            return value
        return "inf" if value > 0 else ("-inf" if value < 0 else "nan")
    if isinstance(value, (np.bool_,)):
        return bool(value)
    if isinstance(value, Path):
        return str(value)
    return value


def write_json_atomic(path, payload):
    """Write ``payload`` as JSON to ``path`` so that readers never see a partial file.

    Parameters
    ----------
    path : str or Path
    payload : dict
        Made JSON-safe by :func:`to_jsonable` (non-finite floats become strings).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(to_jsonable(payload), indent=2, sort_keys=False) + "\n"
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


class BadResult(InputError):
    """A ``result.json`` that is not a JSON object (truncated, empty, a list...)."""


def read_result(path):
    """Read one ``result.json``; ``None`` if it does not exist.

    Raises :class:`BadResult` (one line naming the file) when it cannot be read as UTF-8
    JSON holding an object.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "result.json"
    if not path.exists():
        return None
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise BadResult(f"{path}: cannot be read as JSON ({reason}); expected a result.json "
                        "object (docs/results.md)") from None
    if not isinstance(value, dict):
        raise BadResult(f"{path}: a JSON {type(value).__name__}; expected a result.json "
                        "object (docs/results.md)")
    return value


def read_result_or_none(path):
    """:func:`read_result`, with ``None`` (and a note on stderr) for an unreadable file."""
    try:
        return read_result(path)
    except BadResult as error:
        import sys

        print(f"note: {error}; treated as missing", file=sys.stderr)
        return None
