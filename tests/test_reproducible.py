"""Same config and seed give the same result.json numbers, for every experiment.

Each experiment config may carry ``smoke:`` (a list of Hydra overrides) that makes it
small enough to run twice here; experiments without it are skipped with a reason.
Output locations (``figure_dir``, ``data_dir``) are redirected into a temporary folder.
"""

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from replication.cli import CONFIG_DIR, available_experiments, run_experiment

VOLATILE = ("seconds", "per_second", "wall", "speedup", "provenance", "versions", "config",
            "figures", "mask_file", "path", "_dir", "files_written")
OUTPUT_KEYS = ("figure_dir", "data_dir")


def _compose(name, extra):
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"experiment={name}", *extra])
    return OmegaConf.to_container(cfg, resolve=True)


def _stable(value, key=""):
    """The result without timings, paths and other run-dependent entries."""
    if any(word in key for word in VOLATILE):
        return None
    if isinstance(value, dict):
        return {k: _stable(v, k) for k, v in value.items()}
    if isinstance(value, list):
        return [_stable(v, key) for v in value]
    return value


@pytest.mark.parametrize("name", available_experiments())
def test_same_config_and_seed_give_same_numbers(name, tmp_path):
    plain = _compose(name, [])
    smoke = plain.get("smoke")
    if smoke is None:
        pytest.skip(f"{name}: no smoke overrides in its config")
    if name.startswith("bench"):
        pytest.skip(f"{name}: timings differ between runs by nature")
    results = []
    for run in ("a", "b"):
        redirect = [f"{key}={tmp_path / run / key}" for key in OUTPUT_KEYS if key in plain]
        config = _compose(name, [*smoke, *redirect, f"out={tmp_path / run / 'out'}"])
        results.append(run_experiment(config, tmp_path / run / "out"))
    assert _stable(results[0]) == _stable(results[1])
