"""Fig. 6: the discs' regions refined by radial snakes."""

from __future__ import annotations

import numpy as np

from replication.figures.style import save


def draw(path, frame, contours):
    """Draw radial contours over ``frame`` (H, W).

    ``contours`` is a list of ``((x, y), rho)``: the centre and the radii ``rho`` (K,) of
    ``K`` equal sectors, sector ``k`` starting at angle ``-pi + 2 pi k / K`` (y down).

    Parameters
    ----------
    path : str or Path
        The PNG written.
    frame : (H, W) ndarray
        Background image.
    contours : list of ((x, y), (K,) ndarray)
    """
    import matplotlib.pyplot as plt
    height, width = frame.shape
    fig, ax = plt.subplots(figsize=(5.5, 5.5), dpi=100)
    ax.imshow(frame, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    colours = plt.get_cmap("tab10")
    for k, ((x, y), rho) in enumerate(contours):
        n = len(rho)
        angles = -np.pi + 2 * np.pi * (np.arange(n) + 0.5) / n
        xs = np.append(x + rho * np.cos(angles), x + rho[0] * np.cos(angles[0]))
        ys = np.append(y + rho * np.sin(angles), y + rho[0] * np.sin(angles[0]))
        ax.plot(xs, ys, color=colours(k % 10), lw=1.2)
        ax.plot(x, y, "+", color=colours(k % 10), ms=5)
    ax.set_xlim(-0.5, width - 0.5)
    ax.set_ylim(height - 0.5, -0.5)
    ax.set_title(f"Fig. 6: {len(contours)} regions refined by radial snakes", fontsize=9)
    ax.set_xlabel("x (column)")
    ax.set_ylabel("y (row)")
    fig.tight_layout()
    return save(fig, path)
