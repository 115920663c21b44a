"""Table 1 verdict sensitivity (issue 12): the gathered sweep of ``table1_reading``, read.

The study is a documented Hydra sweep, one ``replicate -m experiment=table1_reading
KEY=v1,v2,...`` command per choice the paper leaves open (``axes`` of
``configs/experiment/table1_sensitivity.yaml``, each holding ``table1_2``'s value); the
sweep's runs are gathered by ``replicate-gather`` into a CSV that is committed
(``data_file``). This runner reads that CSV back, checks that every run was made by the
current code, config and reference files (it recomposes each run's config from its
overrides and compares hashes), and writes the per-reading rates, the figure and the
verdicts of the three Table 1 claims that the report section prints.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np

from replication.errors import check
from replication.experiments import table1_readings
from replication.figures import table1_sensitivity as figure
from replication.progress import progress
from replication.provenance import (
    NOT_RESULT_KEYS,
    PROJECT_ROOT,
    accepted_code_hashes,
    code_hash,
    config_hash,
    legacy_runner,
    path_sha256,
)
from replication.results import read_result
from replication.sweep import PREFIX, inputs_of, overrides_of, read_gathered

# the reading runner, named so that this module's code hash covers it
READING_RUNNER = f"{table1_readings.__name__}:{table1_readings.reading_run.__name__}"
GATHER_COLUMNS = ("run", "experiment", "wall_seconds")


def value_text(value):
    """A config value as written in a Hydra override (and in the run's folder name)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def axis_commands(config):
    """``[(axis, command)]``: the ``replicate -m`` command of every axis of the study."""
    out = []
    for axis in config["axes"]:
        values = ",".join(value_text(v) for v in axis["values"])
        fixed = " ".join(axis.get("fixed") or [])
        out.append((axis, f"replicate -m experiment={config['reading_experiment']} "
                          f"{axis['key']}={values}" + (f" {fixed}" if fixed else "")))
    return out


def sweep_commands(config):
    """Every command that regenerates the study, in order (sweeps, gather, this summary)."""
    csv_path = config["data_file"]
    return ([command for _, command in axis_commands(config)]
            + [f"replicate-gather multirun/{config['reading_experiment']} --output {csv_path}",
               f"replicate experiment={config['name']} force=true"])


def overrides(line):
    """``{key: text}`` of a gathered line's overrides, as written in its run folder's name
    (not as the CSV typed them: ``0.0`` must stay a float), without those that cannot
    change a result (``progress``, ``strict``, ...: ``NOT_RESULT_KEYS``)."""
    pairs = overrides_of(str(line.get("run") or ""))
    return {key[len(PREFIX):]: value for key, value in pairs.items()
            if key[len(PREFIX):].split(".")[0] not in NOT_RESULT_KEYS}


def reference_labels(line):
    """Labels of the reference runs of a gathered line (``references.LABEL.n_runs``)."""
    return [m.group(1) for key in line
            if (m := re.fullmatch(r"references\.(.+)\.n_runs", key))]


def _seeds(line, label):
    """Per-seed records of one reference from a gathered line, in seed order."""
    seeds, i = [], 0
    head = f"references.{label}.seeds."
    while line.get(f"{head}{i}.max_abs_error") is not None:
        seeds.append({"max_abs_error": float(line[f"{head}{i}.max_abs_error"]),
                      "cost": float(line[f"{head}{i}.cost"]),
                      "success": bool(line[f"{head}{i}.success"]),
                      "outcome": line.get(f"{head}{i}.outcome")})
        i += 1
    return seeds


REFERENCE_KEYS = ("n_runs", "n_success", "success_rate", "success_rate_2pct",
                  "n_inactive_valley", "n_elsewhere", "median_cost", "median_max_abs_error",
                  "cost_at_truth", "n_below_truth_cost", "good_max_abs_error",
                  "good_within_2pct", "median_evals")


CONTRACT_NUMERICS = {"reading.numerics.constraint_passes": 1,
                     "reading.numerics.constraint": "jacobi",
                     "reading.numerics.dtype": "float64"}


def reading_key(line):
    """What a run actually used (its ``reading`` block), as a short digest: two runs with
    the same key are the same reading (``cost.frame=150`` is ``table1_2``'s frame, a
    contract model on regenerated data is the suite's data)."""
    used = {key: value for key, value in line.items()
            if key.startswith("reading.") and value is not None}
    numerics = {key: value for key, value in used.items() if key.startswith("reading.numerics.")}
    if numerics == CONTRACT_NUMERICS:
        used.pop("reading.reference", None)
    text = repr(sorted((key, str(value)) for key, value in used.items()))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def reading_of(line):
    """One gathered line as a reading: overrides, hashes, per-reference numbers."""
    refs = {}
    for label in reference_labels(line):
        refs[label] = {key: line.get(f"references.{label}.{key}") for key in REFERENCE_KEYS}
        refs[label]["seeds"] = _seeds(line, label)
    return {"run": str(line.get("run")), "overrides": overrides(line),
            "key": reading_key(line),
            "config_sha256": line.get("provenance.config_sha256"),
            "code_sha256": line.get("provenance.code_sha256"),
            "inputs_sha256": inputs_of(line),
            "wall_seconds": line.get("wall_seconds"),
            "restarts": line.get("reading.restarts") or 1,
            "references": refs}


def compose_reading(experiment, pairs):
    """The resolved config of ``experiment`` with the overrides ``{key: text}``, as
    ``replicate`` composes it (plain dict)."""
    from omegaconf import OmegaConf

    cfg = _composed(experiment, [f"{k}={v}" for k, v in sorted(pairs.items())])
    return OmegaConf.to_container(cfg, resolve=True)


def reading_composer(experiment):
    """``compose(pairs)``: what :func:`compose_reading` gives for ``experiment`` and the
    overrides ``pairs``, without a full Hydra composition per reading (a fifth of a second
    each, most of this study's time): the experiment's config is composed once, on first
    use, and each reading's overrides are applied to a copy of it by Hydra's own override
    code, as the composition applies them once its defaults list is built. A reading that
    overrides a config group (a folder of configs/, which changes the defaults list) is
    composed in full. tests/cloth/test_table1_sensitivity.py compares the two."""
    import copy

    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf

    from replication.cli import CONFIG_DIR

    parser, base = OverridesParser.create(), []

    def compose(pairs):
        overrides = parser.parse_overrides([f"{k}={v}" for k, v in sorted(pairs.items())])
        if any(o.package is not None or (Path(CONFIG_DIR) / o.key_or_group).is_dir()
               for o in overrides):
            return compose_reading(experiment, pairs)
        if not base:
            base.append(_composed(experiment, []))
        config = copy.deepcopy(base[0])
        ConfigLoaderImpl._apply_overrides_to_config(overrides, config)
        return OmegaConf.to_container(config, resolve=True)
    return compose


def _composed(experiment, args):
    """Hydra's composed config (``DictConfig``) of ``experiment`` with overrides ``args``."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from replication.cli import CONFIG_DIR

    args = [f"experiment={experiment}", *args]
    if GlobalHydra.instance().is_initialized():
        return compose(config_name="config", overrides=args)
    with initialize_config_dir(config_dir=CONFIG_DIR, version_base="1.3"):
        return compose(config_name="config", overrides=args)


def _config_hashes(config):
    """Hashes a run of ``config`` may carry: as it is, and with its runner under the name
    it had before a recorded move (:func:`replication.provenance.legacy_runner`)."""
    hashes = {config_hash(config)}
    legacy = legacy_runner(config["runner"])
    if legacy:
        hashes.add(config_hash({**config, "runner": legacy}))
    return hashes


def staleness(readings, experiment, compose=None):
    """Which gathered runs the current code, config and input files would not make.

    Returns ``{"n_runs", "n_stale", "code", "config", "inputs", "no_provenance"}`` (counts;
    ``runs``: the stale run folders with their reasons). ``compose``: a
    :func:`reading_composer` of ``experiment`` to reuse (one is made if not given).
    """
    code_now = code_hash(READING_RUNNER)
    accepted = accepted_code_hashes(READING_RUNNER)
    counts = {"code": 0, "config": 0, "inputs": 0, "no_provenance": 0}
    stale, inputs_now = [], {}
    compose = compose or reading_composer(experiment)
    for reading in readings:
        reasons = []
        if reading["code_sha256"] is None:
            reasons.append("no_provenance")
        else:
            if reading["code_sha256"] not in accepted:
                reasons.append("code")
            try:
                composed = compose(reading["overrides"])
                if reading["config_sha256"] not in _config_hashes(composed):
                    reasons.append("config")
            except Exception:  # an override the current config no longer has
                reasons.append("config")
            for path, sha in reading["inputs_sha256"].items():
                if path not in inputs_now:
                    inputs_now[path] = path_sha256(PROJECT_ROOT / path)
                if inputs_now[path] != sha:
                    reasons.append("inputs")
                    break
        for reason in reasons:
            counts[reason] += 1
        if reasons:
            stale.append({"run": reading["run"], "reasons": reasons})
    return {"n_runs": len(readings), "n_stale": len(stale), **counts, "runs": stale,
            "code_sha256_now": code_now}


def _match(reading, axis):
    """The value text of ``reading`` on ``axis`` (``None`` if it is not on the axis)."""
    pairs = dict(reading["overrides"])
    for fixed in axis.get("fixed") or []:
        key, _, value = fixed.partition("=")
        if pairs.pop(key, None) != value:
            return None
    if set(pairs) != {axis["key"]}:
        return None
    return pairs[axis["key"]]


def _summary_of(reading, labels):
    out = {"run": reading["run"], "config_sha256": reading["config_sha256"],
           "key": reading["key"], "wall_seconds": reading["wall_seconds"],
           "restarts": reading["restarts"]}
    for label in labels:
        ref = reading["references"].get(label)
        if ref is None:
            continue
        out[label] = {key: ref[key] for key in REFERENCE_KEYS}
        out[label]["seed_max_abs_errors"] = [s["max_abs_error"] for s in ref["seeds"]]
    return out


def claim_verdicts(rows, labels, table_label, goal):
    """For each claim, the readings (rows) under which it replicates.

    ``table1``: the lowest-cost run of ``table_label`` has every parameter within 2%;
    ``converges/LABEL``: at least ``goal`` of the seeds within the success tolerance.
    """
    out = {"table1": [r["name"] for r in rows
                      if (r.get(table_label) or {}).get("good_within_2pct")]}
    for label in labels:
        out[f"converges/{label}"] = [r["name"] for r in rows
                                     if (r.get(label) or {}).get("success_rate", 0) >= goal]
    return out


def _copied_table1_2(result):
    """What the verdict rows need of ``table1_2``'s result (the paper's EA as run)."""
    label = result["table_reference"]
    good = result["runs"][label][result["table_runs"]["good"]]
    return {"table_reference": label, "good_relative_errors": good.get("relative_errors"),
            "good_success": good.get("success"),
            "success": {k: {key: s.get(key) for key in ("n_runs", "n_success", "success_rate",
                                                         "n_inactive_valley", "median_cost")}
                        for k, s in result["success"].items()},
            "generations": result["config"]["ea"]["generations"],
            "success_rtol": result["config"]["success_rtol"],
            "config_sha256": result["provenance"]["config_sha256"]}


def sensitivity_study(config, out):
    """Runner of ``table1_sensitivity``: read the gathered sweep, check it, summarise.

    Parameters
    ----------
    config, out
        The resolved ``table1_sensitivity`` config (plain dict, docs/experiments.md) and
        the run's output folder.
    """
    check(len(config["axes"]) > 0, "axes: expected at least one choice to sweep")
    for axis in config["axes"]:
        check(isinstance(axis.get("key"), str) and len(axis.get("values") or []) > 0,
              f"axes: {axis!r}: expected key and a list of values")
    goal = float(config["goal_rate"])
    table_result = read_result(Path(config["table_result"]))
    check(table_result is not None, f"{config['table_result']}: no result.json; run "
                                    "replicate experiment=table1_2 first")
    table1_2 = _copied_table1_2(table_result)
    lines = read_gathered(config["data_file"])
    readings = [reading_of(line) for line in lines]
    progress(f"{config['data_file']}: {len(readings)} runs; checking each against the "
             "current code, config and inputs")
    labels = sorted({label for r in readings for label in r["references"]})
    result = {"commands": sweep_commands(config), "table1_2": table1_2,
              "n_runs": len(readings), "labels": labels, "goal_rate": goal,
              "csv": str(config["data_file"]), "csv_found": bool(lines)}
    if not readings:
        return {**result, "axes": [], "rows": [], "n_readings": 0, "verdicts": {},
                "staleness": None, "figures": []}
    axes, rows, used = [], [], set()
    for axis in config["axes"]:
        points = []
        for value in axis["values"]:
            text = value_text(value)
            found = [r for r in readings if _match(r, axis) == text]
            entry = {"value": text, "found": bool(found)}
            if found:
                used.add(found[0]["run"])
                entry.update(_summary_of(found[0], labels))
                name = f"{axis['key']}={text}" + "".join(
                    f", {f}" for f in axis.get("fixed") or [])
                rows.append({"name": name, "axis": axis["label"],
                             "beyond": found[0]["restarts"] > 1, **entry})
            points.append(entry)
        axes.append({"key": axis["key"], "label": axis["label"],
                     "fixed": list(axis.get("fixed") or []), "beyond": bool(axis.get("beyond")),
                     "points": points})
    others = [r for r in readings if r["run"] not in used]
    for reading in others:
        rows.append({"name": reading["run"] or "(no overrides)", "axis": "other",
                     "beyond": reading["restarts"] > 1, "value": reading["run"],
                     "found": True, **_summary_of(reading, labels)})
    paper_rows = [r for r in rows if not r["beyond"]]
    beyond_rows = [r for r in rows if r["beyond"]]
    table_label = table1_2["table_reference"]
    compose = reading_composer(config["reading_experiment"])   # composes the base once
    default_sha = _config_hashes(compose({}))
    baseline = next((r for r in readings if r["config_sha256"] in default_sha), None)
    same = None
    if baseline is not None:
        same = all(baseline["references"][k]["n_success"] == s["n_success"]
                   and np.isclose(baseline["references"][k]["median_cost"], s["median_cost"],
                                  rtol=1e-12, atol=0)
                   for k, s in table1_2["success"].items() if k in baseline["references"])
    figures = [] if not config.get("figure") else [
        figure.plot(axes, labels, goal=goal, rtol=table1_2["success_rtol"],
                    out_name=config["figure"], figure_dir=config["figure_dir"])]
    result = {
        **result,
        "axes": axes,
        "rows": rows,
        "n_readings": len({r["key"] for r in readings}),
        "n_paper_readings": len({r["key"] for r in paper_rows}),
        "n_beyond_readings": len({r["key"] for r in beyond_rows}),
        "verdicts": claim_verdicts(paper_rows, labels, table_label, goal),
        "beyond_verdicts": claim_verdicts(beyond_rows, labels, table_label, goal),
        "best": {label: max((r for r in paper_rows if label in r),
                            key=lambda r: r[label]["success_rate"], default=None)
                 for label in labels},
        "n_seed_runs": int(sum(r[label]["n_runs"] for r in rows for label in labels
                               if label in r)),
        "n_below_truth_cost": int(sum(r[label]["n_below_truth_cost"] for r in rows
                                      for label in labels if label in r)),
        "baseline_run": None if baseline is None else baseline["run"],
        "baseline_matches_table1_2": same,
        "sweep_seconds": float(sum(r["wall_seconds"] or 0.0 for r in readings)),
        "staleness": staleness(readings, config["reading_experiment"], compose),
        "figures": figures,
    }
    stale = result["staleness"]
    if stale["n_stale"]:
        reasons = ", ".join(f"{key} {stale[key]}" for key in
                            ("code", "config", "inputs", "no_provenance") if stale[key])
        result["warnings"] = [
            f"{stale['n_stale']} of {stale['n_runs']} runs of {config['data_file']} were "
            f"made by other code, config or input files than the current ones ({reasons}): "
            "its numbers are not this code's; re-run the sweep (the result's `commands`) "
            "and gather it again"]
    return result

