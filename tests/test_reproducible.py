"""Same config and seed give the same result.json numbers, for every experiment.

Each experiment may have small settings in the ``smoke`` config group
(``configs/smoke/<experiment>.yaml``, taken with ``+smoke=<experiment>``) that make it
small enough to run twice here; experiments without them are skipped with a reason.
Outputs outside ``out`` are redirected into a temporary folder: the folders
``figure_dir``, ``figures_dir`` and ``data_dir``, and the files ``figure`` and ``manifest``
when they name a folder (``figure: figures/x.png``, not a bare name inside ``figure_dir``).

Timings and throughputs cannot repeat, so they are left out of the comparison (with
paths, versions and the config): a key is a timing when one of its words (split at ``_``
and ``.``) is a time unit (``s``, ``second``, ``seconds``: ``sweep_s``, ``voting_cells_per_s``,
``small_cost_seconds_pop100``) or ``wall``, ``speedup`` or ``load`` (machine load), or when
it is a quotient of two throughputs (``X_over_Y_ratio``). The bench experiments are
compared on everything else (sizes, counts, thread numbers, accuracy checks).
"""

import json
import re
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from replication.cli import CONFIG_DIR, available_experiments, run_experiment
from replication.provenance import NOT_RESULT_KEYS

VOLATILE = ("provenance", "versions", "config", "figure", "plots", "mask_file", "path",
            "_dir", "files_written")
TIMING_WORDS = {"s", "second", "seconds", "wall", "speedup", "load"}
OUTPUT_DIRS = ("figure_dir", "figures_dir", "data_dir")
OUTPUT_FILES = ("figure", "manifest")
REGENERATED = ("regenerated and compared file by file (sha256) with the committed data by "
               "{}, a stronger check: its result.json echoes its config and those hashes")
NOT_REPEATED = {
    "bench": "gathers the results of other experiments from results/ and runs nothing",
    "motion_data": REGENERATED.format("tests/motion/test_synth.py"),
    "motion_multi_data": REGENERATED.format("tests/motion/test_segment.py"),
}


def _compose(name, extra):
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"experiment={name}", *extra])
    return OmegaConf.to_container(cfg, resolve=True)


def is_timing(key):
    """True for the names of timings and throughputs (see the module docstring)."""
    words = set(re.split(r"[_.]", str(key)))
    return bool(words & TIMING_WORDS) or {"over", "ratio"} <= words


def _stable(value, key=""):
    """The result without timings, paths and other run-dependent entries."""
    if is_timing(key) or any(word in key for word in VOLATILE):
        return None
    if isinstance(value, dict):
        return {k: _stable(v, k) for k, v in value.items()}
    if isinstance(value, list):
        return [_stable(v, key) for v in value]
    return value


def _redirect(plain, folder):
    """Overrides that send every output outside ``out`` into ``folder``."""
    overrides = [f"{key}={folder / key}" for key in OUTPUT_DIRS if key in plain]
    for key in OUTPUT_FILES:
        if isinstance(plain.get(key), str) and Path(plain[key]).parent != Path("."):
            overrides.append(f"{key}={folder / key / Path(plain[key]).name}")
    return overrides


def test_timing_rule():
    timings = ["wall_seconds", "sweep_s", "voting_cells_per_s", "voting_cells_per_s_1thread",
               "spring_updates_per_second_compiled_pop100", "speedup_compiled_over_numpy",
               "pipeline_s_median", "load_average_1min", "voting_over_hough_ratio_1thread",
               "analysis_seconds", "paper_ea_small_cost_seconds",
               "bench_cloth.speedup_compiled_over_numpy"]
    numbers = ["numba_threads", "springs_per_individual", "voting_pixels", "omega_values",
               "wald_ratio_quantiles", "max_wald_over_threshold", "per_object_rate",
               "evaluations_per_run", "numpy_vs_compiled_max_difference_h"]
    assert [k for k in timings if not is_timing(k)] == []
    assert [k for k in numbers if is_timing(k)] == []


# experiments whose small settings are another's: the same runner on the same settings
# makes the same runs (checked below, so that a change to either set runs it again)
SAME_RUNS_AS = {"cloth_baselines_budgets": "cloth_baselines"}
NAMES_ONLY = ("name", "figures", "figure")   # keys that name, not make, the runs


def _runs_of(name, folder):
    """What decides the runs of ``name``'s small settings: its composed smoke config
    without :data:`NAMES_ONLY` and the keys that never change a result."""
    config = _compose(name, [f"+smoke={name}", f"out={folder}"])
    return {k: v for k, v in config.items() if k not in NAMES_ONLY + NOT_RESULT_KEYS}


@pytest.mark.slow
@pytest.mark.parametrize("name", available_experiments())
def test_same_config_and_seed_give_same_numbers(name, tmp_path):
    if name in NOT_REPEATED:
        pytest.skip(f"{name}: {NOT_REPEATED[name]}")
    plain = _compose(name, [])
    if not (Path(CONFIG_DIR) / "smoke" / f"{name}.yaml").is_file():
        pytest.skip(f"{name}: no configs/smoke/{name}.yaml")
    other = SAME_RUNS_AS.get(name)
    if other and _runs_of(name, tmp_path) == _runs_of(other, tmp_path):
        pytest.skip(f"{name}: its small settings make {other}'s runs, repeated there")
    results = []
    for run in ("a", "b"):
        out = tmp_path / run / "out"
        config = _compose(name, [f"+smoke={name}", *_redirect(plain, tmp_path / run),
                                 f"out={out}"])
        run_experiment(config, out)
        results.append(json.loads((out / "result.json").read_text()))
        # a file written outside the output folders names no staging folder
        manifest = config.get("manifest")
        if isinstance(manifest, str) and Path(manifest).is_file():
            assert ".partial-" not in Path(manifest).read_text(), manifest
    assert _stable(results[0]) == _stable(results[1])
