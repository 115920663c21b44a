"""Table 1 verdict sensitivity: success rate against each choice, seeds as points."""

from __future__ import annotations

import math

import numpy as np

from replication.figures.cloth_common import save

TABLE1_RTOL = 0.02   # Table 1's tolerance (replication.experiments.table1_readings)

COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple")


def plot(axes, labels, *, goal, rtol, out_name, figure_dir="figures", n_cols=4):
    """One pair of panels per swept choice: above, the success rate of each reference run
    against the choice's values (dotted: the goal); below, every seed's largest
    |relative error| of its final best individual (log scale; dashed: the success
    tolerance; dotted: Table 1's 2%), slightly spread sideways per reference run.

    Parameters
    ----------
    axes : list of dict
        ``{"label", "fixed", "beyond", "points": [{"value", "found", LABEL: {...}}]}`` as
        ``table1_sensitivity`` writes them.
    labels : list of str
        Reference runs.
    goal : float
        Success rate the paper's "generally" is read as.
    rtol : float
        Success tolerance (relative error of every parameter).
    out_name : str
    figure_dir : str or Path
    n_cols : int
    """
    import matplotlib.pyplot as plt
    n_rows = max(1, math.ceil(len(axes) / n_cols))
    fig, grid = plt.subplots(2 * n_rows, n_cols, figsize=(4.2 * n_cols, 4.6 * n_rows),
                             squeeze=False, layout="constrained",
                             height_ratios=[1, 2] * n_rows)
    for index in range(n_rows * n_cols):
        top = grid[2 * (index // n_cols), index % n_cols]
        bottom = grid[2 * (index // n_cols) + 1, index % n_cols]
        if index >= len(axes):
            top.axis("off")
            bottom.axis("off")
            continue
        _panel(top, bottom, axes[index], labels, goal=goal, rtol=rtol)
    handles = [plt.Line2D([], [], color=c, marker="o", ls="-", label=label)
               for c, label in zip(COLOURS, labels)]
    fig.legend(handles=handles, loc="outside upper center", ncols=len(labels))
    return save(fig, out_name, figure_dir)


def _panel(top, bottom, axis, labels, *, goal, rtol):
    values = [p["value"] for p in axis["points"]]
    x = np.arange(len(values))
    width = 0.6 / max(1, len(labels))
    for k, (label, colour) in enumerate(zip(labels, COLOURS)):
        rates = [p[label]["success_rate"] if p["found"] and label in p else np.nan
                 for p in axis["points"]]
        offset = (k - (len(labels) - 1) / 2) * width
        top.plot(x + offset, rates, color=colour, marker="o", ms=4, lw=1)
        for i, point in enumerate(axis["points"]):
            if not point["found"] or label not in point:
                continue
            errors = np.asarray(point[label]["seed_max_abs_errors"], float)
            spread = np.linspace(-width / 3, width / 3, max(1, errors.size))
            bottom.scatter(i + offset + spread, np.maximum(errors, 1e-6), s=8, color=colour,
                           alpha=0.7, lw=0)
    top.axhline(goal, color="grey", ls=":", lw=1)
    top.set_ylim(-0.05, 1.05)
    top.set_xticks(x, [])
    top.set_xlim(-0.5, len(values) - 0.5)
    top.set_ylabel("success rate", fontsize=8)
    title = axis["label"] + (" (beyond the paper)" if axis.get("beyond") else "")
    if axis.get("fixed"):
        title += "\n" + ", ".join(axis["fixed"])
    top.set_title(title, fontsize=9)
    bottom.axhline(rtol, color="grey", ls="--", lw=1)
    bottom.axhline(TABLE1_RTOL, color="grey", ls=":", lw=1)
    bottom.set_yscale("log")
    bottom.set_xticks(x, [v + ("" if p["found"] else "\n(not run)")
                          for v, p in zip(values, axis["points"])], fontsize=7)
    bottom.set_xlim(-0.5, len(values) - 0.5)
    bottom.set_ylabel("seed: max |rel. error|", fontsize=8)
