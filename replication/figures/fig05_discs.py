"""Fig. 5: the EA's retained discs, drawn as in the paper.

Circles are the discs; small squares the rotation centres ``(xi, eta)``; a straight line
joins each centre to its disc (omitted when the centre is outside the picture); a short
line from each disc's centre is the velocity of the disc's rotation there.
"""

from __future__ import annotations

import numpy as np

from replication.figures.style import save


def draw(path, frame, discs, rotating, *, tick_scale=8.0):
    """Draw the discs ``(n, 6)`` = ``(x, y, r, xi, eta, omega)`` over ``frame`` (H, W).

    ``rotating`` (n,) bool marks discs kept as rotating (solid yellow) against those
    taken for the static background (dashed cyan). Velocity ticks are
    ``tick_scale`` times the velocity (pixels/frame).

    Parameters
    ----------
    path : str or Path
        The PNG written.
    frame : (H, W) ndarray
    discs : (n, 6) ndarray
    rotating : (n,) bool ndarray
    tick_scale : float
    """
    import matplotlib.pyplot as plt
    height, width = frame.shape
    fig, ax = plt.subplots(figsize=(5.5, 5.5), dpi=100)
    ax.imshow(frame, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    for (x, y, r, xi, eta, omega), moving in zip(np.asarray(discs), np.asarray(rotating)):
        colour, style = ("yellow", "-") if moving else ("cyan", "--")
        ax.add_patch(plt.Circle((x, y), r, fill=False, color=colour, ls=style, lw=1.0))
        if 0 <= xi <= width - 1 and 0 <= eta <= height - 1:
            ax.plot([xi, x], [eta, y], color=colour, lw=0.6, ls=style)
            ax.plot(xi, eta, "s", ms=3.5, mfc="none", mec=colour)
        u, v = -omega * (y - eta), omega * (x - xi)
        ax.plot([x, x + tick_scale * u], [y, y + tick_scale * v], color="red", lw=1.2)
    ax.set_xlim(-0.5, width - 0.5)
    ax.set_ylim(height - 0.5, -0.5)
    ax.set_title(f"Fig. 5: EA discs (yellow: rotating, {int(np.sum(rotating))}; "
                 f"cyan: static, {int(np.size(rotating) - np.sum(rotating))})", fontsize=9)
    ax.set_xlabel("x (column)")
    ax.set_ylabel("y (row)")
    fig.tight_layout()
    return save(fig, path)
