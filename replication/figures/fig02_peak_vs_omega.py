"""Fig. 2: accumulation space maxima against omega."""

from __future__ import annotations

import numpy as np

from replication.figures.style import save


def draw(path, omega, peak, *, best=None, refined=None, truth=None):
    """Plot ``peak`` (m,) against ``omega`` (m,) with vertical marks for the best peak,
    the refined and the true omega (each optional); write to ``path``.

    Parameters
    ----------
    path : str or Path
        The PNG written.
    omega, peak : (m,) array_like
    best, refined, truth : float, optional
    """
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=100)
    ax.plot(omega, peak, ".-", color="black", lw=1, ms=3, label="peak of F(omega)")
    for value, colour, label in ((best, "tab:red", "best peak (paper)"),
                                 (refined, "tab:blue", "refined"),
                                 (truth, "tab:green", "truth")):
        if value is not None:
            ax.axvline(value, color=colour, ls="--", lw=1, label=f"{label}: {value:.4f}")
    ax.set_xlabel("omega (rad/frame)")
    ax.set_ylabel("votes in the best cell")
    ax.set_xlim(np.min(omega), np.max(omega))
    ax.set_title("Fig. 2: accumulation space maxima vs omega")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return save(fig, path)
