"""Best cost per generation of every paper-EA run (Tables 1-2 study), one panel per data."""

from __future__ import annotations

from replication.figures.cloth_common import new_figure, save


def plot(runs, *, out_name, figure_dir="figures"):
    """``runs``: ``{label: [record with 'history' (best cost per generation), 'success']}``.

    Parameters
    ----------
    runs : dict
    out_name : str
        File name.
    figure_dir : str or Path
        Folder of the file (a relative one is inside the project).
    """
    fig, axes = new_figure(len(runs))
    for ax, (label, records) in zip(axes[0], runs.items()):
        for record in records:
            success = record.get("success")
            color = "tab:green" if success else ("tab:red" if success is False else "tab:blue")
            ax.semilogy(range(len(record["history"])), record["history"], color=color,
                        alpha=0.6, lw=1)
        ax.set_title(f"paper EA, {label}: {len(records)} seeds (green: within 1%)", fontsize=10)
        ax.set_xlabel("generation")
        ax.set_ylabel("best cost")
    return save(fig, out_name, figure_dir)
