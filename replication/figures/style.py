"""Shared figure settings, so that figures are byte-stable between runs."""

from pathlib import Path


SAVE_OPTIONS = {"dpi": 110, "metadata": {"Software": None}}


def save(fig, path):
    """Save ``fig`` as PNG without timestamps and close it; returns the path as str.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or Path
    """
    import matplotlib.pyplot as plt
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, **SAVE_OPTIONS)
    plt.close(fig)
    return str(path)
