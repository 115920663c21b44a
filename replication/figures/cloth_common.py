"""Shared plotting helpers of the cloth identification figures (matplotlib Agg)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from replication.provenance import PROJECT_ROOT  # noqa: E402


def save(fig, name, figure_dir="figures"):
    """Write ``fig`` to ``figure_dir/name`` deterministically (a relative ``figure_dir`` is
    inside the project); return the path as written in the report.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    name : str
    figure_dir : str or Path
        Folder of the file (a relative one is inside the project).
    """
    import matplotlib.pyplot as plt
    folder = Path(figure_dir)
    if not folder.is_absolute():
        folder = PROJECT_ROOT / folder
    folder.mkdir(parents=True, exist_ok=True)
    fig.savefig(folder / name, dpi=110, metadata={"Software": None})
    plt.close(fig)
    return f"{figure_dir}/{name}"


def new_figure(n_cols, *, n_rows=1, width=5.0, height=3.8):
    """A figure with ``n_rows x n_cols`` axes (always a 2-D array).

    Parameters
    ----------
    n_cols, n_rows : int
    width, height : float
        Inches per panel.
    """
    import matplotlib.pyplot as plt
    return plt.subplots(n_rows, n_cols, figsize=(width * n_cols, height * n_rows),
                        squeeze=False, layout="constrained")
