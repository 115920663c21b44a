"""Hashes that tie a result to the config and code that made it."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
PROJECT_ROOT = PACKAGE_DIR.parent


def config_hash(config):
    """sha256 of a resolved config, independent of key order and of where results go."""
    config = {key: value for key, value in config.items() if key not in ("out", "resume")}
    text = json.dumps(config, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def code_hash():
    """sha256 over the package's Python sources and the pinned requirements."""
    digest = hashlib.sha256()
    files = sorted(PACKAGE_DIR.rglob("*.py"))
    lock = PROJECT_ROOT / "requirements.lock"
    if lock.exists():
        files.append(lock)
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
