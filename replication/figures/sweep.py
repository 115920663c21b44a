"""Figure: one metric of a sweep against a swept override (draws what ``sweep.series`` gives)."""

from __future__ import annotations


from replication.figures import style


def plot_series(lines, *, numeric, metric, x_label, path):
    """Each run as a point and the median over seeds as a line, one line per group.

    Parameters
    ----------
    lines : list of dict
        ``{"label", "points": [(x, y)], "median": [(x, median)]}`` (``sweep.series``).
    numeric : bool
        Numeric x axis; otherwise the x values are categories, in sorted order.
    metric, x_label : str
        Axis labels.
    path : str or Path
        The PNG to write.
    """
    import matplotlib.pyplot as plt
    categories = sorted({xv for line in lines for xv, _ in line["points"]}) if not numeric \
        else None
    place = (lambda xv: xv) if numeric else categories.index
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for index, line in enumerate(lines):
        colour = f"C{index % 10}"
        ax.plot([place(xv) for xv, _ in line["points"]], [y for _, y in line["points"]],
                "o", color=colour, alpha=0.4, markersize=4)
        # categories have no order between them: their medians are markers, not a line
        ax.plot([place(xv) for xv, _ in line["median"]], [y for _, y in line["median"]],
                "-" if numeric else "none", color=colour, marker="s", markersize=5,
                label=line["label"] or "median over seeds")
    if not numeric:
        ax.set_xticks(range(len(categories)), categories, rotation=30, ha="right")
    ax.set_xlabel(x_label)
    ax.set_ylabel(metric)
    ax.set_title(f"{metric} against {x_label}: runs (points), median over seeds "
                 f"({'line' if numeric else 'squares'})", fontsize=9)
    if lines:
        ax.legend(fontsize=7)
    fig.tight_layout()
    return style.save(fig, path)
