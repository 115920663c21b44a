"""Cost against frame size (bench_motion_scale): time and centre error against the side."""

from __future__ import annotations

import numpy as np

from replication.figures.style import save

COLOURS = {"exact": "tab:red", "pyramid": "tab:blue", "segmentation (pyramid)": "tab:green"}


def draw(path, rows, fits, multi_rows=(), multi_fits=()):
    """Log-log time and centre error against the frame side; write to ``path``.

    Parameters
    ----------
    rows : list of dict
        ``method, side, noise_255, seconds, centre_px`` per measurement (one centre).
    fits : list of dict
        ``method, noise_255, sides, seconds_exponent_vs_pixels`` per curve.
    multi_rows, multi_fits : list of dict
        The same for the segmentation (``max_centre_px``: the worst object's centre error).
    """
    import matplotlib.pyplot as plt
    rows = list(rows) + [dict(row, method="segmentation (pyramid)",
                              centre_px=row["max_centre_px"]) for row in multi_rows
                         if row["max_centre_px"] is not None]
    fits = list(fits) + list(multi_fits)
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4), dpi=100)
    noises = sorted({row["noise_255"] for row in rows})
    markers = dict(zip(noises, "os^v"))
    for fit in fits:
        mine = [row for row in rows if row["method"] == fit["method"]
                and row["noise_255"] == fit["noise_255"]]
        sides = np.array([row["side"] for row in mine], dtype=float)
        seconds = np.array([row["seconds"] for row in mine])
        label = (f"{fit['method']}, noise {fit['noise_255']:g}/255: "
                 f"t ~ pixels^{fit['seconds_exponent_vs_pixels']:.2f}")
        style = {"color": COLOURS[fit["method"]], "marker": markers[fit["noise_255"]],
                 "ls": "-" if fit["noise_255"] == noises[0] else "--", "ms": 5, "lw": 1}
        left.loglog(sides, seconds, label=label, **style)
        right.loglog(sides, [max(row["centre_px"], 1e-4) for row in mine],
                     label=f"{fit['method']}, noise {fit['noise_255']:g}/255", **style)
    sides = np.array(sorted({row["side"] for row in rows}), dtype=float)
    anchor = min(row["seconds"] for row in rows if row["side"] == sides[0])
    for power, text, line in ((1.0, "pixels^1", ":"), (1.5, "pixels^1.5 (side^3)", "-.")):
        left.loglog(sides, anchor * (sides / sides[0]) ** (2 * power), color="grey", lw=0.8,
                    ls=line, label=f"reference {text}")
    left.set_xlabel("frame side (pixels)")
    left.set_ylabel("wall-clock seconds (best run)")
    left.set_title("time against frame size")
    right.loglog(sides, sides / 512.0, color="grey", lw=0.8, ls=":",
                 label="1 px at 512, in proportion")
    right.set_xlabel("frame side (pixels)")
    right.set_ylabel("centre error (pixels)")
    right.set_title("refined centre error (segmentation: worst object)")
    for ax in (left, right):
        ax.set_xticks(sides)
        ax.set_xticklabels([str(int(side)) for side in sides])
        ax.minorticks_off()
        ax.legend(fontsize=6.5)
    fig.tight_layout()
    return save(fig, path)
