"""Fig. 1: a frame of the sequence with a velocity field from a classical optical flow."""

from __future__ import annotations

import numpy as np

from replication.figures.style import save


def draw(path, frame, flow, *, step=12, method="TV-L1"):
    """Draw ``frame`` (H, W) with the arrows of ``flow`` (2, H, W) = (u along x, v along y).

    Arrows are drawn every ``step`` pixels, magnified 4x; the file is written to ``path``.

    Parameters
    ----------
    path : str or Path
        The PNG written.
    frame : (H, W) ndarray
    flow : (2, H, W) ndarray
    step : int
    method : str
        Name of the flow method, for the title.
    """
    import matplotlib.pyplot as plt
    u, v = flow
    rows, cols = np.mgrid[step // 2: frame.shape[0]: step, step // 2: frame.shape[1]: step]
    fig, ax = plt.subplots(figsize=(5, 5), dpi=100)
    ax.imshow(frame, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    ax.quiver(cols, rows, u[rows, cols], v[rows, cols], color="yellow", angles="xy",
              scale_units="xy", scale=0.25, width=0.004)
    ax.set_title(f"Fig. 1: frame 0 and {method} flow (arrows x4)")
    ax.set_xlabel("x (column)")
    ax.set_ylabel("y (row)")
    fig.tight_layout()
    return save(fig, path)
