"""Figure: the identifier blind on outside data: outcome of every dataset over (K, tau)."""

from __future__ import annotations

import numpy as np

from replication.figures.cloth_common import save

OUTCOMES = (   # (name, colour, marker, label)
    ("ok", "tab:green", "o", "within tolerance"),
    ("warned", "tab:orange", "^", "wrong, warned"),
    ("silent", "tab:red", "X", "wrong, no warning"),
    ("refused", "black", "s", "refused"),
)


def outcome(row):
    """``ok``, ``warned``, ``silent`` or ``refused`` for one dataset row."""
    if row["refused"]:
        return "refused"
    if row["success"]:
        return "ok"
    return "warned" if row["warned"] else "silent"


def plot(by_method, rtol, out_name, figure_dir="figures"):
    """One row of two panels per method: each dataset at its true (K, tau), marked by the
    outcome of that method's answer (marker size grows with the position noise, noise-free
    data hollow); and the answer's largest relative parameter error against the share of
    particle-steps the constraint moved.

    Parameters
    ----------
    by_method : dict
        ``{method: rows}``, rows as :func:`replication.experiments.outside_identify.
        answers_of` gives them.
    rtol : float
        The success tolerance (dashed line).
    out_name : str
    figure_dir : str or Path
    """
    import matplotlib.pyplot as plt
    n = len(by_method)
    fig, grid = plt.subplots(n, 2, figsize=(12, 4.6 * n), layout="constrained",
                             squeeze=False)
    for (method, rows), (left, right) in zip(by_method.items(), grid):
        _panels(method, rows, rtol, left, right)
    return save(fig, out_name, figure_dir)


def _panels(method, rows, rtol, left, right):
    noise = np.array([r["noise_h"] for r in rows])
    size = np.where(noise > 0, 20 + 12 * (np.log10(np.maximum(noise, 1e-12)) + 7), 30)
    for name, colour, marker, label in OUTCOMES:
        chosen = [i for i, r in enumerate(rows) if outcome(r) == name]
        if not chosen:
            continue
        faces = ["none" if noise[i] == 0 else colour for i in chosen]
        left.scatter([rows[i]["K"] for i in chosen], [rows[i]["tau"] for i in chosen],
                     s=size[chosen], marker=marker, facecolors=faces, edgecolors=colour,
                     label=f"{label} ({len(chosen)})")
        errors = [rows[i]["max_abs_error"] if rows[i]["max_abs_error"] is not None
                  else np.nan for i in chosen]
        right.scatter([rows[i]["constraint_share"] for i in chosen],
                      np.maximum(errors, 1e-12), s=size[chosen], marker=marker,
                      facecolors=faces, edgecolors=colour)
    left.set_xscale("log")
    left.set_yscale("log")
    left.set_xlabel("true K")
    left.set_ylabel("true tau")
    left.set_title(f"{method}: outcome per dataset (hollow: noise 0; larger: more noise)",
                   fontsize=10)
    left.legend(fontsize=8, loc="best")
    right.set_yscale("log")
    right.set_xlabel("share of free particle-steps the constraint moved")
    right.set_ylabel("largest |relative error| of the answer")
    right.axhline(rtol, color="grey", ls="--", lw=1)
    right.set_title(f"{method}: error against constraint activity", fontsize=10)
