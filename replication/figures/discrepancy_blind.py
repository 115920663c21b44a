"""Figure: the blind study's confusion matrix and gap shrink (reads its result)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402


def plot_blind(result, path):
    """Confusion matrix (hidden vs called) and gap before/after per dataset; returns path.

    Parameters
    ----------
    result : dict
        The ``discrepancy_blind`` result.
    path : str or Path
        The PNG written.
    """
    import matplotlib.pyplot as plt
    summary = result["summary"]
    hidden, calls = summary["hidden"], summary["calls"]
    matrix = np.array([[summary["confusion"][e][c] for c in calls] for e in hidden])
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    axes[0].imshow(matrix, cmap="Blues")
    for (i, j), value in np.ndenumerate(matrix):
        if value:
            axes[0].text(j, i, str(value), ha="center", va="center")
    axes[0].set_xticks(range(len(calls)), calls, rotation=60, ha="right", fontsize=8)
    axes[0].set_yticks(range(len(hidden)), hidden, fontsize=8)
    axes[0].set_xlabel("called")
    axes[0].set_ylabel("hidden (gust: outside the library)")
    axes[0].set_title("blind naming: confusion matrix")
    rows = result["datasets"]
    colours = ["0.6" if r["expected"] == "none" else ("tab:green" if r["correct"] else "tab:red")
               for r in rows]
    axes[1].scatter([r["gap_before"] for r in rows], [r["gap_after"] for r in rows],
                    c=colours, s=18)
    low = min(min(r["gap_after"] for r in rows), min(r["gap_before"] for r in rows))
    high = max(r["gap_before"] for r in rows)
    axes[1].plot([low, high], [low, high], "k:", label="no change")
    axes[1].plot([low, high], [low / 5, high / 5], "k--", label="5x shrink")
    axes[1].set_xscale("log")
    axes[1].set_yscale("log")
    axes[1].set_xlabel("held-out rollout RMS, base model (h)")
    axes[1].set_ylabel("after adding named effect (h)")
    axes[1].set_title("gap (green: correct call, red: wrong, grey: effect-free)")
    axes[1].legend()
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
