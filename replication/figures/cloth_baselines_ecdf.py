"""Baselines study: ECDF of evaluations to success, and median convergence curves."""

from __future__ import annotations

import numpy as np

from replication.figures.cloth_common import new_figure, save


def _ecdf(ax, hits, budget, label):
    n = len(hits)
    reached = np.sort([h for h in hits if h is not None])
    x = np.r_[1, reached, budget]
    y = np.r_[0, np.arange(1, reached.size + 1), reached.size] / n
    ax.step(x, y, where="post", label=label)


def plot(summary, checkpoints, budget, *, ecdf_name, convergence_name, figure_dir="figures"):
    """``summary[data][optimiser]`` with ``evals_to_success`` and ``median_curve``.

    Parameters
    ----------
    summary : dict
        ``summary[data][optimiser]``: ``evals_to_success`` (per seed, None when never) and
        ``median_curve`` (best cost at each checkpoint).
    checkpoints : list of int
        Evaluation counts of the curves.
    budget : int
        The largest budget (x range).
    ecdf_name, convergence_name : str
        File names of the two figures.
    figure_dir : str or Path
        Folder of the file (a relative one is inside the project).
    """
    fig, axes = new_figure(len(summary))
    for ax, (label, by_opt) in zip(axes[0], summary.items()):
        for name, s in by_opt.items():
            _ecdf(ax, s["evals_to_success"], budget, name)
        ax.set_xscale("log")
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("evaluations")
        ax.set_ylabel("fraction of seeds with all parameters within 1%")
        ax.set_title(f"{label}: evaluations to success (ECDF)")
        ax.legend(fontsize=7)
    ecdf = save(fig, ecdf_name, figure_dir)
    fig, axes = new_figure(len(summary))
    for ax, (label, by_opt) in zip(axes[0], summary.items()):
        for name, s in by_opt.items():
            curve = np.asarray(s["median_curve"], dtype=float)
            ax.loglog(checkpoints, np.where(curve > 0, curve, np.nan), label=name)
        ax.set_xlabel("evaluations")
        ax.set_ylabel("median best cost over seeds")
        ax.set_title(f"{label}: convergence")
        ax.legend(fontsize=7)
    return [ecdf, save(fig, convergence_name, figure_dir)]
