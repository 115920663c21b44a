"""Verdict sensitivity (replication.experiments.sensitivity): the rate against each choice,
runs as points."""

from __future__ import annotations

import math

import numpy as np

from replication.figures.style import save


def draw(path, study, *, ylabel, title, n_cols=4):
    """One panel per swept choice: the rate of each reading (line; the base's value as
    a filled square), the per-run or per-sequence points it averages (grey, spread
    sideways) and the goal (dotted).

    Parameters
    ----------
    path : str or Path
    study : dict
        As :func:`replication.experiments.sensitivity.run_study` returns it.
    ylabel, title : str
    n_cols : int
    """
    import matplotlib.pyplot as plt
    axes = study["axes"]
    n_cols = min(n_cols, len(axes))
    n_rows = max(1, math.ceil(len(axes) / n_cols))
    fig, grid = plt.subplots(n_rows, n_cols, figsize=(3.6 * n_cols, 3.0 * n_rows),
                             squeeze=False, layout="constrained", sharey=True)
    jitter = np.random.default_rng(0)   # fixed: the figure is byte-stable
    for index, ax in enumerate(grid.flat):
        if index >= len(axes):
            ax.axis("off")
            continue
        rows = [r for r in study["readings"] if r["axis"] == index]
        x = np.arange(len(rows))
        for k, row in enumerate(rows):
            points = np.asarray(row.get("points") or [], dtype=float)
            if points.size:
                ax.scatter(k + jitter.uniform(-0.15, 0.15, points.size), points, s=9,
                           color="0.6", alpha=0.6, lw=0)
        rates = [r["rate"] for r in rows]
        ax.plot(x, rates, "-o", color="tab:blue", ms=5)
        base = [k for k, r in enumerate(rows) if r["is_base"]]
        ax.plot(base, [rates[k] for k in base], "s", color="tab:red", ms=7,
                label="the experiment's own setting")
        ax.axhline(study["goal_rate"], color="k", ls=":", lw=1)
        ax.set_xticks(x, [_text(r["value"]) for r in rows], fontsize=8)
        ax.set_title(axes[index]["label"] + (" (beyond the paper)" if axes[index]["beyond"]
                                             else ""), fontsize=9)
        ax.set_ylim(-0.05, 1.05)
        if index % n_cols == 0:
            ax.set_ylabel(ylabel)
    fig.suptitle(title, fontsize=10)
    return save(fig, path)


def _text(value):
    if isinstance(value, list):
        return ",".join(_text(v) for v in value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    return "null" if value is None else str(value)
