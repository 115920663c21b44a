"""Verdict sensitivity: one experiment's runner under each reading the paper leaves open.

A study's config inherits the whole config of the experiment whose verdict it explains
(``defaults: [BASE, _self_]`` in ``configs/experiment``), so its config hash covers the
base's settings, and adds a ``sensitivity`` block::

    sensitivity:
      axes:                    # one axis per choice; each holds the base's value
        - {key: flow.erode, values: [0, 2, 5, 10], label: "erosion (px)"}
        - {key: flow.tvl1.attachment, values: [5, 15, 50], label: "...", fixed: {k: v}}
      goal_rate: 0.5           # the rate the verdict asks for
      max_axes: null           # smoke settings: only the first axes / values
      max_values: null

A reading is the base config with ``key = value`` (and the axis's ``fixed`` overrides)
set, as ``replicate experiment=BASE key=value`` would run it; the base runner runs it
in-process, its result is scored by the study's ``score`` function (a rate and per-run
points) and only those numbers are kept. Readings that set the same values (the base's
value on every axis) run once.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path

from replication.errors import InputError, check
from replication.progress import progress


def set_dotted(config, key, value):
    """Set ``config[a][b][c] = value`` for ``key = "a.b.c"`` (creating dicts on the way)."""
    *path, last = key.split(".")
    node = config
    for part in path:
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        check(isinstance(child, dict), f"sensitivity axis {key!r}: {part!r} is not a group")
        node = child
    node[last] = value


def get_dotted(config, key, default=None):
    """``config[a][b][c]`` for ``key = "a.b.c"``, or ``default`` when a part is missing."""
    node = config
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return default
        node = node[part]
    return node


def readings(config):
    """``[(axis index, value, overrides)]`` of the study: every axis value, with the
    axis's ``fixed`` overrides, limited by ``max_axes`` and ``max_values``."""
    block = config.get("sensitivity") or {}
    axes = list(block.get("axes") or [])
    check(len(axes) > 0, "sensitivity.axes: expected at least one axis")
    if block.get("max_axes") is not None:
        axes = axes[:int(block["max_axes"])]
    out = []
    for index, axis in enumerate(axes):
        check(isinstance(axis, dict) and "key" in axis and axis.get("values"),
              f"sensitivity.axes[{index}]: expected {{key, values, label}}")
        values = list(axis["values"])
        if block.get("max_values") is not None:
            values = values[:int(block["max_values"])]
        for value in values:
            overrides = {**(axis.get("fixed") or {}), axis["key"]: value}
            out.append((index, value, overrides))
    return axes, out


def reading_config(config, overrides):
    """The base config (the study's without its ``sensitivity``, ``report`` and output
    keys) with ``overrides`` set."""
    base = copy.deepcopy({k: v for k, v in config.items()
                          if k not in ("sensitivity", "report", "figure")})
    for key, value in overrides.items():
        set_dotted(base, key, copy.deepcopy(value))
    return base


def run_study(config, out, runner, score):
    """Run ``runner`` under every reading of ``config`` and score each result.

    Parameters
    ----------
    config : dict
        The study's resolved config (the base experiment's config plus ``sensitivity``).
    out : str or Path
        The study's output folder; each reading runs in ``out/readings/NN``.
    runner : callable(config, out) -> dict
        The base experiment's runner.
    score : callable(result) -> dict
        ``{"rate": float, "points": [float], ...}`` of one reading's result (the points
        are the per-run or per-sequence values the rate averages).

    Returns
    -------
    dict with ``axes`` (key, label, values, base value, beyond) and ``readings`` (axis,
    key, value, overrides, is_base, rate, points, seconds and what ``score`` adds).
    """
    axes, plan = readings(config)
    done, rows = {}, []
    base_values = {axis["key"]: get_dotted(config, axis["key"]) for axis in axes}
    for number, (index, value, overrides) in enumerate(plan):
        axis = axes[index]
        signature = repr(sorted((k, repr(v)) for k, v in overrides.items()
                                if get_dotted(config, k, object()) != v))
        if signature not in done:
            start = time.perf_counter()
            folder = Path(out) / "readings" / f"{len(done):02d}"
            folder.mkdir(parents=True, exist_ok=True)
            try:
                scored = score(runner(reading_config(config, overrides), folder))
            except InputError as error:
                raise InputError(f"sensitivity reading {axis['key']}={value!r}: {error}") \
                    from error
            done[signature] = {**scored, "seconds": time.perf_counter() - start}
            progress(f"sensitivity {number + 1}/{len(plan)}: {axis['key']}={value!r} -> "
                     f"rate {scored['rate']:.2f} ({done[signature]['seconds']:.1f} s)")
        rows.append({"axis": index, "key": axis["key"], "label": axis.get("label", axis["key"]),
                     "value": value, "overrides": overrides,
                     "is_base": signature == "[]", **done[signature]})
    return {"axes": [{"key": a["key"], "label": a.get("label", a["key"]),
                      "values": [r["value"] for r in rows if r["axis"] == i],
                      "base_value": base_values[a["key"]], "beyond": bool(a.get("beyond"))}
                     for i, a in enumerate(axes)],
            "readings": rows, "n_distinct_readings": len(done),
            "goal_rate": float((config.get("sensitivity") or {}).get("goal_rate", 0.5))}


def verdict(study, *, meets):
    """Which readings meet the goal: ``(meeting, total)``, ``meeting`` the reading rows
    for which ``meets(row)`` is true (distinct readings only; beyond-the-paper axes
    left out), ``total`` the number of distinct readings of the paper."""
    seen, meeting = set(), []
    beyond = {i for i, a in enumerate(study["axes"]) if a["beyond"]}
    for row in study["readings"]:
        if row["axis"] in beyond:
            continue
        key = repr(sorted((k, repr(v)) for k, v in row["overrides"].items())) \
            if not row["is_base"] else "base"
        if key in seen:
            continue
        seen.add(key)
        if meets(row):
            meeting.append(row)
    return meeting, len(seen)
