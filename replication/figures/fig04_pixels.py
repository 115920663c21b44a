"""Fig. 4: pixels that verify the IRC equation for the parameters found."""

from __future__ import annotations


from replication.figures.style import save


def draw(path, closeness, *, region=None, label_outline=None):
    """Show ``closeness`` (H, W) in [0, 1] (1 = verifies the equation, 0 = does not or has
    too small a gradient), the detected blob ``region`` (H, W bool) and the true object
    outline ``label_outline`` (H, W bool) if given; write to ``path``.

    Parameters
    ----------
    path : str or Path
        The PNG written.
    closeness : (H, W) ndarray
    region, label_outline : (H, W) bool ndarray, optional
    """
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5, 5), dpi=100)
    ax.imshow(closeness, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    if region is not None:
        ax.contour(region, levels=[0.5], colors="tab:red", linewidths=1)
    if label_outline is not None:
        ax.contour(label_outline, levels=[0.5], colors="tab:green", linewidths=0.8,
                   linestyles="dashed")
    ax.set_title("Fig. 4: pixels verifying the IRC equation\n(red: blob, green dashed: truth)",
                 fontsize=9)
    ax.set_xlabel("x (column)")
    ax.set_ylabel("y (row)")
    fig.tight_layout()
    return save(fig, path)
