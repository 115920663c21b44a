"""Paper Fig. 8: the periodic mesh of masses and its three spring families."""

from __future__ import annotations

import numpy as np

from replication.figures.style import save

FAMILY_STYLE = {  # spring types -> (label, colour)
    (0, 1): ("structural (types 0, 1)", "black"),
    (2, 3): ("shear (types 2, 3)", "tab:blue"),
    (4, 5): ("flexion (types 4, 5)", "tab:red"),
}


def _draw_springs(ax, x, a, b, kind, types, colour, bend):
    for s in np.flatnonzero(np.isin(kind, types)):
        p, q = x[a[s]], x[b[s]]
        if bend:  # flexion springs overlap structural ones: draw them as arcs
            mid = 0.5 * (p + q)
            normal = np.array([-(q - p)[1], (q - p)[0]])
            control = mid + 0.18 * normal
            t = np.linspace(0, 1, 20)[:, None]
            curve = (1 - t) ** 2 * p + 2 * (1 - t) * t * control + t ** 2 * q
            ax.plot(curve[:, 0], curve[:, 1], color=colour, lw=0.9)
        else:
            ax.plot([p[0], q[0]], [p[1], q[1]], color=colour, lw=0.9)


def draw(path, *, positions, a, b, kind, pinned, n, zoom):
    """Draw the mesh (left) and a ``zoom x zoom`` corner with every spring (right).

    Parameters
    ----------
    path : str or Path
        The PNG written.
    positions : (n*n, 3) ndarray
        Rest positions.
    a, b, kind : (S,) int ndarray
        Spring ends and types.
    pinned : (k, 2) int ndarray
    n : int
    zoom : int
        Particles per side of the corner shown.
    """
    import matplotlib.pyplot as plt
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 5))
    x = positions[:, :2]
    structural = np.isin(kind, (0, 1))
    for s in np.flatnonzero(structural):
        left.plot(*x[[a[s], b[s]]].T, color="0.6", lw=0.6)
    left.scatter(x[:, 0], x[:, 1], s=6, color="black", zorder=3)
    pins = x[pinned[:, 0] * n + pinned[:, 1]]
    left.scatter(pins[:, 0], pins[:, 1], s=80, marker="s", color="tab:orange", zorder=4,
                 label="pinned corners")
    left.set_title(f"{n} x {n} mesh (structural springs)")
    left.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12))

    i, j = np.divmod(np.arange(n * n), n)
    inside = (i < zoom) & (j < zoom)
    keep = inside[a] & inside[b]
    for (types, (label, colour)), bend in zip(FAMILY_STYLE.items(), (False, False, True)):
        _draw_springs(right, x, a[keep], b[keep], kind[keep], types, colour, bend)
        right.plot([], [], color=colour, label=label)
    right.scatter(x[inside, 0], x[inside, 1], s=30, color="black", zorder=3)
    right.set_title(f"the three spring families ({zoom} x {zoom} corner)")
    right.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8)
    for ax in (left, right):
        ax.set_aspect("equal")
        ax.invert_yaxis()
        ax.set_xlabel("x = j h")
        ax.set_ylabel("y = i h")
    fig.suptitle("Fig. 8: the periodic mesh of masses and springs")
    fig.tight_layout()
    return save(fig, path)
