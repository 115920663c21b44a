"""``replicate``: the Hydra entry point (docs/results.md).

The only module that sees a DictConfig. Each experiment config names a ``runner``
(``module:function``); the runner receives the resolved config as a plain dict and the
output folder, returns its result keys, and this module adds the common keys and writes
``result.json`` atomically.
"""

from __future__ import annotations

import importlib
import os
import sys
import tempfile
import time
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from replication.errors import InputError
from replication.provenance import code_hash, config_hash
from replication.results import package_versions, read_result, write_json_atomic

CONFIG_DIR = str(Path(__file__).resolve().parent.parent / "configs")

if not OmegaConf.has_resolver("or_default"):
    OmegaConf.register_new_resolver("or_default", lambda value, default: value or default)


def available_experiments():
    """Names of the experiment configs in ``configs/experiment``."""
    return sorted(p.stem for p in (Path(CONFIG_DIR) / "experiment").glob("*.yaml"))


def resolve_runner(spec):
    """Import ``module:function``."""
    module_name, _, function_name = spec.partition(":")
    return getattr(importlib.import_module(module_name), function_name)


def check_writable(out):
    """Refuse an output folder that cannot be created or written, before any work."""
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=out, prefix=".write-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as error:
        raise InputError(f"out={out}: cannot write there ({error.strerror or error})") from None


def run_experiment(config, out):
    """Run the experiment described by the plain-dict ``config``; return the result dict."""
    if not config.get("runner"):
        raise InputError(
            "no experiment chosen: pass experiment=NAME, one of "
            + ", ".join(available_experiments())
        )
    runner = resolve_runner(config["runner"])
    check_writable(out)
    provenance = {"config_sha256": config_hash(config),
                  "code_sha256": code_hash(config["runner"])}
    previous = read_result(Path(out) / "result.json") if config.get("resume") else None
    if previous is not None and previous.get("provenance") == provenance:
        print(f"up to date: {Path(out) / 'result.json'} (resume=true)", file=sys.stderr)
        return previous
    start = time.perf_counter()
    result = runner(config, Path(out))
    wall = time.perf_counter() - start
    payload = {
        "experiment": config.get("name"),
        "config": config,
        "seed": config.get("seed"),
        "versions": package_versions(),
        "wall_seconds": wall,
        "provenance": provenance,
    }
    payload.update(result)
    write_json_atomic(Path(out) / "result.json", payload)
    print(f"wrote {Path(out) / 'result.json'}", file=sys.stderr)
    return payload


@hydra.main(config_path=CONFIG_DIR, config_name="config", version_base="1.3")
def _hydra_main(cfg: DictConfig):
    try:
        config = OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)
        out = config["out"] or HydraConfig.get().runtime.output_dir
        config["out"] = out
        run_experiment(config, out)
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    except FileNotFoundError as error:
        print(f"error: {error.filename}: file not found", file=sys.stderr)
        sys.exit(2)


def main():
    """Console-script entry point."""
    # Hydra creates the run folder (``out``) before the task runs: refuse an unwritable one
    # here, with one line, instead of Hydra's traceback.
    for arg in sys.argv[1:]:
        if arg.startswith("out=") and "," not in arg:
            try:
                check_writable(arg[len("out="):])
            except InputError as error:
                print(f"error: {error}", file=sys.stderr)
                sys.exit(2)
    _hydra_main()


if __name__ == "__main__":
    main()
