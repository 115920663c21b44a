"""Paper Figs. 9-10: cost over (K, tau), log colour scale, with the EA's path on top."""

from __future__ import annotations

import numpy as np
from matplotlib.colors import LogNorm

from replication.figures.cloth_common import new_figure, save


def plot(panels, path, *, reference, title, out_name, figure_dir="figures"):
    """``panels[f"{cost}/{window}"]`` with ``K, tau, log, cost`` grids; ``path`` rows
    ``(K, tau, best cost)`` per generation; ``reference`` the true ``(K, tau)``.

    Parameters
    ----------
    panels : dict
    path : list of (3,) sequence
    reference : (2,) tuple
    title : str
    out_name : str
        File name.
    figure_dir : str or Path
        Folder of the file (a relative one is inside the project).
    """
    names = list(panels)
    costs = list(dict.fromkeys(name.split("/")[0] for name in names))
    windows = list(dict.fromkeys(name.split("/")[1] for name in names))
    fig, axes = new_figure(len(windows), n_rows=len(costs), width=5.2, height=4.2)
    path = np.asarray(path, dtype=float)
    for r, kind in enumerate(costs):
        for c, window in enumerate(windows):
            ax, p = axes[r, c], panels[f"{kind}/{window}"]
            grid = np.asarray(p["cost"], dtype=float)
            positive = grid[np.isfinite(grid) & (grid > 0)]
            floor = positive.min() if positive.size else 1e-30
            shown = np.where(np.isfinite(grid), np.maximum(grid, floor), np.nan)
            mesh = ax.pcolormesh(p["K"], p["tau"], shown, shading="nearest",
                                 norm=LogNorm(vmin=floor, vmax=np.nanmax(shown)),
                                 cmap="viridis")
            fig.colorbar(mesh, ax=ax, label=f"{kind} cost")
            if p["log"]:
                ax.set_xscale("log")
                ax.set_yscale("log")
            ax.plot(path[:, 0], path[:, 1], "-o", color="white", ms=2, lw=0.8,
                    label="paper EA best per generation")
            ax.plot(path[-1, 0], path[-1, 1], "x", color="red", ms=8, label="EA final")
            ax.plot(*reference, "*", color="orange", ms=10, label="reference")
            ax.set_xlim(p["K"][0], p["K"][-1])
            ax.set_ylim(p["tau"][0], p["tau"][-1])
            ax.set_xlabel("K")
            ax.set_ylabel("tau")
            ax.set_title(f"{title}: {kind} cost, {window} window", fontsize=9)
    axes[0, 0].legend(fontsize=6, loc="lower left")
    return save(fig, out_name, figure_dir)
