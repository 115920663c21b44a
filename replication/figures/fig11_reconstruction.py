"""Paper Fig. 11: reference animation beside re-simulations from given parameters."""

from __future__ import annotations

import io

import numpy as np
from PIL import Image

from replication.figures.style import SAVE_OPTIONS, save


def _mesh(ax, x, n, colour):
    grid = x.reshape(n, n, 3)
    for line in grid:
        ax.plot(line[:, 0], line[:, 1], line[:, 2], color=colour, lw=0.5)
    for line in grid.transpose(1, 0, 2):
        ax.plot(line[:, 0], line[:, 1], line[:, 2], color=colour, lw=0.5)


def _axes(ax, limits):
    ax.set_xlim(*limits[0])
    ax.set_ylim(*limits[1])
    ax.set_zlim(*limits[2])
    ax.set_box_aspect([high - low for low, high in limits])
    ax.view_init(elev=20, azim=-60)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_zticks([])


def _limits(columns):
    stacked = np.concatenate([c.reshape(-1, 3) for c in columns])
    low, high = stacked.min(axis=0), stacked.max(axis=0)
    return list(zip(low, high))


def draw(path, *, columns, titles, frames, n, dt):
    """Rows are the given frame indices, columns the runs.

    Parameters
    ----------
    path : str or Path
        The PNG written.
    columns : list of (T, n*n, 3) ndarray
        Positions of each run.
    titles : list of str
    frames : list of int
    n : int
    dt : float
        Time between frames (row labels).
    """
    import matplotlib.pyplot as plt
    limits = _limits(columns)
    colours = ["black", "tab:blue", "tab:red", "tab:green"]
    fig = plt.figure(figsize=(3.2 * len(columns), 2.8 * len(frames)))
    for r, t in enumerate(frames):
        for c, (positions, title) in enumerate(zip(columns, titles)):
            ax = fig.add_subplot(len(frames), len(columns), r * len(columns) + c + 1,
                                 projection="3d")
            _mesh(ax, positions[t], n, colours[c % len(colours)])
            _axes(ax, limits)
            if r == 0:
                ax.set_title(title, fontsize=9)
            if c == 0:
                ax.text2D(-0.05, 0.5, f"t = {t * dt:.2f} s", transform=ax.transAxes,
                          rotation=90, va="center")
    fig.suptitle("Fig. 11: original animation and reconstructions")
    fig.tight_layout()
    return save(fig, path)


def animate(path, *, columns, titles, frames, n, dt):
    """An animated GIF of the columns side by side over ``frames``.

    Parameters
    ----------
    path : str or Path
        The GIF written.
    columns : list of (T, n*n, 3) ndarray
    titles : list of str
    frames : list of int
    n : int
    dt : float
    """
    import matplotlib.pyplot as plt
    limits = _limits(columns)
    colours = ["black", "tab:blue", "tab:red", "tab:green"]
    images = []
    for t in frames:
        fig = plt.figure(figsize=(3.0 * len(columns), 3.0))
        for c, (positions, title) in enumerate(zip(columns, titles)):
            ax = fig.add_subplot(1, len(columns), c + 1, projection="3d")
            _mesh(ax, positions[t], n, colours[c % len(colours)])
            _axes(ax, limits)
            ax.set_title(title, fontsize=8)
        fig.suptitle(f"t = {t * dt:.3f} s", fontsize=9)
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=70, metadata=SAVE_OPTIONS["metadata"])
        plt.close(fig)
        images.append(Image.open(buffer).convert("P", palette=Image.Palette.ADAPTIVE))
    images[0].save(path, save_all=True, append_images=images[1:], duration=80, loop=0)
    return str(path)
