"""Cost-growth curves (log-log), one panel per curve, the fitted exponent in the legend."""

from __future__ import annotations

from matplotlib import ticker
import numpy as np

from replication.figures.style import save


def draw(path, curves, *, title):
    """One log-log panel per curve.

    Parameters
    ----------
    path : str or Path
    curves : list of dict
        ``{"title", "xlabel", "ylabel", "series": [{"label", "x", "y", "exponent"}]}``.
    title : str
    """
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(curves), figsize=(4.2 * len(curves), 3.4),
                             squeeze=False, layout="constrained")
    for ax, curve in zip(axes[0], curves):
        for series in curve["series"]:
            slope = series.get("exponent")
            label = series["label"] + (f" (slope {slope:.2f})" if slope is not None else "")
            ax.loglog(np.asarray(series["x"], float), np.asarray(series["y"], float), "-o",
                      ms=4, label=label)
        # plain numbers: the measured sizes on x, 1-2-5 steps on y, no minor labels
        sizes = sorted({float(v) for series in curve["series"] for v in series["x"]})
        ax.xaxis.set_major_locator(ticker.FixedLocator(sizes))
        ax.yaxis.set_major_locator(ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_formatter(ticker.FuncFormatter(lambda v, _: f"{v:g}"))
            axis.set_minor_formatter(ticker.NullFormatter())
        ax.set_title(curve["title"], fontsize=9)
        ax.set_xlabel(curve["xlabel"])
        ax.set_ylabel(curve["ylabel"])
        ax.legend(fontsize=7)
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
    fig.suptitle(title, fontsize=10)
    return save(fig, path)
