"""Shared plotting helpers of the cloth identification figures (matplotlib Agg)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from replication.provenance import PROJECT_ROOT  # noqa: E402

FIGURE_DIR = PROJECT_ROOT / "figures"


def save(fig, name):
    """Write ``fig`` to ``figures/name`` deterministically; return the relative path."""
    FIGURE_DIR.mkdir(parents=True, exist_ok=True)
    path = FIGURE_DIR / name
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)
    return f"figures/{name}"


def new_figure(n_cols, *, n_rows=1, width=5.0, height=3.8):
    """A figure with ``n_rows x n_cols`` axes (always a 2-D array)."""
    return plt.subplots(n_rows, n_cols, figsize=(width * n_cols, height * n_rows),
                        squeeze=False, layout="constrained")
