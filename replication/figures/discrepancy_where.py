"""Figure: where the base model and the data disagree (reads a discrepancy result)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402


def plot_where(result, out_dir):
    """Residual map over the mesh, structure over time, and the held-out gap; returns paths.

    Parameters
    ----------
    result : dict
        The workflow's result (``where``, ``gap``, ``settings``).
    out_dir : str or Path
    """
    import matplotlib.pyplot as plt
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    where = result["where"]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    image = axes[0].imshow(np.asarray(where["map"]), origin="upper", cmap="magma")
    axes[0].set_title("window-summed residual / noise floor")
    axes[0].set_xlabel("j")
    axes[0].set_ylabel("i")
    fig.colorbar(image, ax=axes[0])
    if len(where["Q_by_window"]) == len(where["window_starts"]) > 0:
        axes[1].semilogy(where["window_starts"], np.maximum(where["Q_by_window"], 1e-3), "o-")
    axes[1].axhline(result["settings"]["q_threshold"], color="k", ls="--", label="threshold")
    axes[1].set_xlabel("frame")
    axes[1].set_ylabel("Q (1 = noise)")
    axes[1].set_title("structure over time")
    axes[1].legend()
    labels = ["rollout", "one step"]
    before = [result["gap"]["before"]["rollout"], result["gap"]["before"]["one_step"]]
    after = [result["gap"]["after"]["rollout"], result["gap"]["after"]["one_step"]]
    xs = np.arange(2)
    axes[2].bar(xs - 0.2, before, 0.4, label="base model")
    axes[2].bar(xs + 0.2, after, 0.4, label="with named effect")
    axes[2].axhline(result["gap"]["one_step_noise_floor_h"], color="k", ls=":",
                    label="one-step noise floor")
    axes[2].set_xticks(xs, labels)
    axes[2].set_yscale("log")
    axes[2].set_ylabel("held-out RMS error (h)")
    named = ", ".join(e["name"] for e in result["named_effects"]) or "none"
    axes[2].set_title(f"gap (named: {named})")
    axes[2].legend(fontsize=8)
    fig.tight_layout()
    path = out_dir / "discrepancy_where.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [path]
