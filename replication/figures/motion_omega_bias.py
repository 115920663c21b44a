"""The omega bias of the best peak (motion_omega_bias): against speed, texture, noise."""

from __future__ import annotations

import numpy as np

from replication.figures.style import save

COLOURS = {"suite": "tab:red", "forward": "tab:orange", "central3": "tab:brown",
           "gaussian": "tab:blue", "gaussian_central3": "tab:purple", "exact": "black",
           "exact_noise": "tab:grey", "refined": "tab:green"}
ORDER = tuple(COLOURS)


def _lines(ax, summary, axis, x_key, *, errors=False):
    """One line per variant of ``axis``: mean bias against ``x_key``."""
    for variant in ORDER:
        mine = sorted((s for s in summary if s["axis"] == axis and s["variant"] == variant),
                      key=lambda s: abs(s[x_key]))
        if not mine:
            continue
        x = [abs(s[x_key]) for s in mine]
        y = [s["bias_pct"] for s in mine]
        if errors:
            ax.errorbar(x, y, yerr=[s["bias_sd_pct"] for s in mine], color=COLOURS[variant],
                        marker="o", ms=3, lw=1, capsize=2, label=variant)
        else:
            ax.plot(x, y, color=COLOURS[variant], marker="o", ms=3, lw=1, label=variant)


def _frame(ax, summary, axis, x_key):
    """Log x axis with the case values as plain ticks; y limits on the measured values
    (the leading-order curves leave their range where ``k d`` is not small)."""
    mine = [s for s in summary if s["axis"] == axis]
    values = sorted({abs(s[x_key]) for s in mine})
    ax.set_xscale("log")
    ax.set_xticks(values)
    ax.set_xticklabels([f"{v:g}" for v in values], fontsize=7)
    ax.minorticks_off()
    biases = [s["bias_pct"] for s in mine]
    ax.set_ylim(min(biases + [0.0]) - 3.0, max(biases) + 3.0)


def _predicted(ax, predictions, axis, x_key):
    """Leading-order curves: suite = spatial + temporal, gaussian = temporal,
    gaussian_central3 = -2 temporal."""
    mine = sorted((p for p in predictions if p["axis"] == axis), key=lambda p: abs(p[x_key]))
    x = [abs(p[x_key]) for p in mine]
    temporal = np.array([p["temporal_pct"] for p in mine])
    spatial = np.array([p["spatial_pct"] for p in mine])
    for variant, values in (("suite", spatial + temporal), ("gaussian", temporal),
                            ("gaussian_central3", -2.0 * temporal)):
        ax.plot(x, values, color=COLOURS[variant], ls=":", lw=1.2)
    ax.plot([], [], color="grey", ls=":", label="leading order")


def draw(path, summary, predictions, paper_rows, reference):
    """Six panels: bias against rotation speed, wavelength, noise, noise / |omega|, cell
    size, and the paper-like sequence; write to ``path``.

    Parameters
    ----------
    path : str or Path
    summary : list of dict
        ``omega_bias.summarise`` output.
    predictions : list of dict
        ``axis, omega, wavelength, spatial_pct, temporal_pct``.
    paper_rows : list of dict
        ``condition, variant, bias_pct`` on the paper-like sequence.
    reference : dict
        ``omega``, ``wavelength`` of the reference case.
    """
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 3, figsize=(15, 8.5), dpi=100)
    (speed, texture, noise), (collapse, cell, paper) = axes
    _lines(speed, summary, "speed", "omega")
    _predicted(speed, predictions, "speed", "omega")
    _frame(speed, summary, "speed", "omega")
    speed.set_xlabel("|omega| (rad/frame)")
    speed.set_title(f"rotation speed (wavelength {reference['wavelength']:g} px, no noise)")
    _lines(texture, summary, "texture", "wavelength")
    _predicted(texture, predictions, "texture", "wavelength")
    _frame(texture, summary, "texture", "wavelength")
    texture.set_xlabel("texture wavelength (px)")
    texture.set_title(f"texture (|omega| = {abs(reference['omega']):g}, no noise)")
    _lines(noise, summary, "noise", "noise_255", errors=True)
    noise.set_xlabel("noise sd (x/255)")
    noise.set_title(f"noise (|omega| = {abs(reference['omega']):g}, mean +- sd over seeds)")
    for axis, marker in (("noise", "o"), ("half_speed", "s")):
        mine = sorted((s for s in summary if s["axis"] == axis
                       and s["variant"] == "exact_noise" and s["noise_255"] > 0),
                      key=lambda s: s["noise_255"])
        x = [s["noise_255"] / abs(s["omega"]) for s in mine]
        label = f"|omega| = {abs(mine[0]['omega']):g}" if mine else axis
        collapse.plot(x, [s["bias_pct"] for s in mine], marker=marker, color="tab:grey",
                      lw=1, label=f"exact_noise, {label}")
        collapse.plot(x, [s["normalised_pct"] for s in mine], marker=marker, mfc="none",
                      color="tab:cyan", lw=1, ls="--", label=f"peak of F/|omega|, {label}")
    collapse.set_xscale("log")
    collapse.set_xlabel("noise / |omega| (x/255 per rad/frame)")
    collapse.set_title("noise term: oracle derivatives + noise")
    _lines(cell, summary, "cell", "cell", errors=True)
    cell.set_xlabel("accumulator cell (px)")
    cell.set_title("cell size (oracle + noise)")
    conditions = ("noise-free", "noisy")
    variants = [v for v in ORDER if any(r["variant"] == v for r in paper_rows)]
    width = 0.8 / len(conditions)
    for k, condition in enumerate(conditions):
        values = [next(r["bias_pct"] for r in paper_rows if r["variant"] == v
                       and r["condition"] == condition) for v in variants]
        paper.bar(np.arange(len(variants)) + (k - 0.5) * width, values, width,
                  color=[COLOURS[v] for v in variants], alpha=0.5 + 0.5 * k,
                  edgecolor="black", label=condition)
    paper.set_xticks(np.arange(len(variants)))
    paper.set_xticklabels(variants, rotation=30, ha="right", fontsize=7)
    paper.set_title("paper-like sequence (light: noise-free, dark: as stored)")
    for ax in axes.flat:
        ax.axhline(0.0, color="black", lw=0.6)
        ax.set_ylabel("best-peak |omega| error (%)")
        ax.grid(alpha=0.3)
        if ax is not paper:
            ax.legend(fontsize=6.5)
    fig.tight_layout()
    return save(fig, path)
