"""Fig. 7: the rotations refined by accumulation restricted to each object's region."""

from __future__ import annotations

import numpy as np

from replication.figures.style import save


def draw(path, frame, panels, *, truth=()):
    """Left: ``frame`` with each object's region and refined centre; right: each object's
    restricted accumulator (normalised to its peak) in image coordinates.

    ``panels`` is a list of ``{acc (ny, nx), extent (x0, x1, y1, y0), xi, eta, omega,
    mask (H, W) bool}``; ``truth`` a list of true centres ``(xi, eta)`` (drawn as x).

    Parameters
    ----------
    path : str or Path
        The PNG written.
    frame : (H, W) ndarray
    panels : list of dict
    truth : sequence of tuple
    """
    import matplotlib.pyplot as plt
    height, width = frame.shape
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 5), dpi=100)
    colours = plt.get_cmap("tab10")
    left.imshow(frame, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    right.imshow(np.zeros_like(frame), cmap="gray", vmin=0, vmax=1,
                 extent=(-0.5, width - 0.5, height - 0.5, -0.5))
    for k, panel in enumerate(panels):
        colour = colours(k % 10)
        left.contour(panel["mask"].astype(float), levels=[0.5], colors=[colour],
                     linewidths=1.0)
        acc = panel["acc"].astype(float) / max(float(panel["acc"].max()), 1.0)
        right.imshow(np.ma.masked_less(acc, 0.15), cmap="magma", vmin=0, vmax=1,
                     extent=panel["extent"], interpolation="nearest", alpha=0.9)
        for ax in (left, right):
            ax.plot(panel["xi"], panel["eta"], "s", ms=5, mfc="none", mec=colour)
        left.annotate(f"{k + 1}: omega={panel['omega']:+.4f}", (panel["xi"], panel["eta"]),
                      xytext=(4, -6), textcoords="offset points", color=colour, fontsize=7)
    for xi, eta in truth:
        for ax in (left, right):
            ax.plot(xi, eta, "x", color="lime", ms=6)
    for ax in (left, right):
        ax.set_xlim(-0.5, width - 0.5)
        ax.set_ylim(height - 0.5, -0.5)
        ax.set_xlabel("x (column)")
    left.set_ylabel("y (row)")
    left.set_title("Fig. 7: objects, refined centres (squares), truth (x)", fontsize=9)
    right.set_title("restricted accumulators (votes / peak)", fontsize=9)
    fig.tight_layout()
    return save(fig, path)
