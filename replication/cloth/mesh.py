"""The 17x17 mesh and its six spring types (docs/cloth-model.md, paper Fig. 8)."""

from __future__ import annotations

import numpy as np

N_TYPES = 6
TYPE_NAMES = (
    "structural j", "structural i", "shear (i,j)-(i+1,j+1)", "shear (i,j+1)-(i+1,j)",
    "flexion j", "flexion i",
)
# type -> family, for the 5-parameter model: 0 structural, 1 shear, 2 flexion
FAMILY_OF_TYPE = np.array([0, 0, 1, 1, 2, 2])

DEFAULT_N = 17
DEFAULT_SIDE = 1.5


def spacing(n=DEFAULT_N, side=DEFAULT_SIDE):
    """Grid spacing ``h = side / (n - 1)``.

    Parameters
    ----------
    n : int
        Particles per side.
    side : float
    """
    return side / (n - 1)


def springs(n=DEFAULT_N):
    """All springs of an ``n x n`` mesh.

    Returns
    -------
    a, b : (S,) int64 ndarray
        Flat particle indices ``p = i*n + j`` of the spring ends (``d = x_b - x_a``).
    kind : (S,) int64 ndarray
        Spring type 0..5 as in docs/cloth-model.md, springs ordered by type.
    """
    if n < 3:
        raise ValueError(f"n={n}: a mesh needs at least 3 particles per side")
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    p = i * n + j
    pairs = [
        (p[:, :-1], p[:, 1:]),          # 0: (i,j)-(i,j+1)
        (p[:-1, :], p[1:, :]),          # 1: (i,j)-(i+1,j)
        (p[:-1, :-1], p[1:, 1:]),       # 2: (i,j)-(i+1,j+1)
        (p[:-1, 1:], p[1:, :-1]),       # 3: (i,j+1)-(i+1,j)
        (p[:, :-2], p[:, 2:]),          # 4: (i,j)-(i,j+2)
        (p[:-2, :], p[2:, :]),          # 5: (i,j)-(i+2,j)
    ]
    a = np.concatenate([first.ravel() for first, _ in pairs]).astype(np.int64)
    b = np.concatenate([second.ravel() for _, second in pairs]).astype(np.int64)
    kind = np.concatenate([np.full(first.size, t) for t, (first, _) in enumerate(pairs)])
    return a, b, kind.astype(np.int64)


def flat_rest_positions(n=DEFAULT_N, side=DEFAULT_SIDE):
    """The contract's initial state: flat sheet ``x = (j*h, i*h, 0)``, shape ``(n*n, 3)``.

    Parameters
    ----------
    n : int
    side : float
    """
    h = spacing(n, side)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    x = np.zeros((n, n, 3))
    x[..., 0] = j * h
    x[..., 1] = i * h
    return x.reshape(n * n, 3)


def reference_rest_lengths(h):
    """Rest lengths ``(l_01, l_23, l_45) = (h, h*sqrt(2), 2h)``."""
    return np.array([h, h * np.sqrt(2.0), 2.0 * h])


def type_lengths(positions, n, *, statistic="mean"):
    """One length per spring type from recorded positions, over every frame given:
    ``"mean"``, each spring's mean length over the frames, averaged over the type's
    springs; ``"median"``, the median of all the type's lengths in all the frames.

    The one place spring lengths per type are measured: cost normalisation (first frame),
    the search bounds (mean over all frames) and the regression's starting lengths (median
    over a subsample of frames).

    Parameters
    ----------
    positions : (n*n, 3), (n, n, 3), (F, n*n, 3) or (F, n, n, 3) ndarray
    n : int
        Particles per side.
    statistic : "mean" or "median"

    Returns
    -------
    (6,) ndarray
    """
    x = np.asarray(positions, dtype=float).reshape(-1, n * n, 3)
    a, b, kind = springs(n)
    length = np.linalg.norm(x[:, b] - x[:, a], axis=2)
    if statistic == "mean":
        per_spring = length.mean(axis=0)
        return np.array([per_spring[kind == t].mean() for t in range(N_TYPES)])
    if statistic == "median":
        return np.array([np.median(length[:, kind == t]) for t in range(N_TYPES)])
    raise ValueError(f"statistic={statistic!r}: expected 'mean' or 'median'")
