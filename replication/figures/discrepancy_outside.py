"""Figure: the outside blind study: detection limit, gap, exact answers by kind."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402


def _snr_bins(rows, edges):
    """Exact-answer rate per bin of the weakest effect's SNR (finite SNR only)."""
    snr = np.array([r["min_snr"] for r in rows])
    exact = np.array([r["exact"] for r in rows], dtype=float)
    centres, rates, counts = [], [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        inside = (snr >= lo) & (snr < hi)
        if inside.any():
            centres.append(np.sqrt(lo * hi))
            rates.append(exact[inside].mean())
            counts.append(int(inside.sum()))
    return np.array(centres), np.array(rates), counts


def plot_outside(result, path):
    """Three panels: exact-answer rate against the weakest effect's SNR (datasets as
    points, noise-free ones at the right edge), held-out gap before/after, and the exact
    rate per kind above the detection limit. Returns the path.

    Parameters
    ----------
    result : dict
        The ``discrepancy_outside`` result: ``datasets`` (one row per dataset) and
        ``summary``.
    path : str or Path
        The PNG written.
    """
    import matplotlib.pyplot as plt
    rows = result["datasets"]
    summary = result["summary"]
    limit = summary["detection_snr"]
    fig, axes = plt.subplots(1, 3, figsize=(17, 5.2))
    effects = [r for r in rows if r["kinds"]]
    finite = [r for r in effects if np.isfinite(r["min_snr"]) and r["min_snr"] > 0]
    jitter = np.random.default_rng(0)
    if finite:
        snr = np.array([r["min_snr"] for r in finite])
        edges = np.geomspace(max(snr.min(), 1e-3) / 1.01, snr.max() * 1.01, 9)
        centres, rates, counts = _snr_bins(finite, edges)
        axes[0].plot(centres, rates, "o-", color="tab:blue", label="exact rate per bin")
        for c, r, n in zip(centres, rates, counts):
            axes[0].annotate(f"n={n}", (c, r), textcoords="offset points", xytext=(0, 6),
                             fontsize=7, ha="center")
        axes[0].scatter(snr, [r["exact"] + jitter.uniform(-0.04, 0.04) for r in finite],
                        s=10, c=["tab:green" if r["exact"] else "tab:red" for r in finite],
                        alpha=0.6)
        right = snr.max() * 3
    else:
        right = limit * 10
    noise_free = [r for r in effects if not np.isfinite(r["min_snr"])]
    if noise_free:
        axes[0].scatter([right] * len(noise_free),
                        [r["exact"] + jitter.uniform(-0.04, 0.04) for r in noise_free],
                        marker="s", s=14,
                        c=["tab:green" if r["exact"] else "tab:red" for r in noise_free],
                        label="noise-free (SNR infinite)")
    axes[0].axvline(limit, color="k", ls="--", label=f"stated detection limit ({limit:g})")
    axes[0].set_xscale("log")
    axes[0].set_ylim(-0.1, 1.15)
    axes[0].set_xlabel("SNR of the weakest effect present (generator's definition)")
    axes[0].set_ylabel("exact answer (1) or not (0)")
    axes[0].set_title("detection limit")
    axes[0].legend(fontsize=8, loc="lower right")
    shown = [r for r in rows if np.isfinite(r["gap_before"]) and r["gap_before"] > 0
             and r["gap_after"] > 0]
    if shown:
        colours = ["0.6" if not r["kinds"] else ("tab:green" if r["exact"] else "tab:red")
                   for r in shown]
        before = np.array([r["gap_before"] for r in shown])
        after = np.array([r["gap_after"] for r in shown])
        axes[1].scatter(before, after, c=colours, s=14)
        low, high = min(before.min(), after.min()), before.max()
        axes[1].plot([low, high], [low, high], "k:", label="no change")
        axes[1].plot([low, high], [low / 5, high / 5], "k--", label="5x shrink")
        axes[1].set_xscale("log")
        axes[1].set_yscale("log")
        axes[1].legend(fontsize=8)
    axes[1].set_xlabel("held-out rollout RMS, base model (h)")
    axes[1].set_ylabel("with the named effects (h)")
    axes[1].set_title("gap (green exact, red not, grey effect-free)")
    kinds = summary["by_kind"]
    names = list(kinds)
    values = [kinds[k]["exact_above"] if kinds[k]["exact_above"] is not None else 0.0
              for k in names]
    axes[2].barh(range(len(names)), values, color="tab:blue")
    for y, k in enumerate(names):
        axes[2].text(0.01, y, f"n={kinds[k]['n_above']}", va="center", fontsize=7,
                     color="white")
    axes[2].set_yticks(range(len(names)), names, fontsize=8)
    axes[2].set_xlim(0, 1)
    axes[2].set_xlabel("exact-answer rate above the detection limit")
    axes[2].set_title("by kind (datasets holding it)")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
