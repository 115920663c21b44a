"""Fig. 3: the accumulation space at the best omega."""

from __future__ import annotations


from replication.figures.style import save


def draw(path, acc, extent, *, peak, truth=None, omega=None):
    """Show ``acc`` (ny, nx) over ``extent`` (x_min, x_max, y_max, y_min) with the peak
    ``(xi, eta)`` and the true centre (optional); write to ``path``.

    Parameters
    ----------
    path : str or Path
        The PNG written.
    acc : (ny, nx) ndarray
    extent : tuple
    peak : (2,) tuple
    truth : (2,) tuple, optional
    omega : float, optional
        For the title.
    """
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5, 5), dpi=100)
    ax.imshow(acc, cmap="inferno", extent=extent, interpolation="nearest")
    ax.plot(*peak, "+", color="cyan", ms=14, mew=1.5, label=f"peak ({peak[0]:g}, {peak[1]:g})")
    if truth is not None:
        ax.plot(*truth, "x", color="lime", ms=10, mew=1.5,
                label=f"truth ({truth[0]:g}, {truth[1]:g})")
    title = "Fig. 3: accumulation space"
    if omega is not None:
        title += f" at omega = {omega:.4f}"
    ax.set_title(title)
    ax.set_xlabel("xi")
    ax.set_ylabel("eta")
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return save(fig, path)
