"""Spring sums, normals and mesh coordinates of recorded frames, vectorised over frames.

Every quantity here is a function of positions (and velocities) only; the effect library
and the linear fit build their regressors from them. Shapes use ``F`` frames, ``P = n*n``
particles and ``S`` springs.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from replication.cloth.mesh import N_TYPES, springs


def scatter_matrix(n):
    """Sparse ``(P, S)`` matrix sending a per-spring vector to its ends: ``+1`` on end ``a``,
    ``-1`` on end ``b`` (the sign of the contract's ``f_a = k (L - l) d / L``)."""
    a, b, _ = springs(n)
    n_springs = a.size
    rows = np.concatenate([a, b])
    cols = np.concatenate([np.arange(n_springs), np.arange(n_springs)])
    vals = np.concatenate([np.ones(n_springs), -np.ones(n_springs)])
    return sparse.csr_matrix((vals, (rows, cols)), shape=(n * n, n_springs))


def scatter(matrix, per_spring):
    """Apply a ``(P, S)`` scatter matrix to per-spring vectors.

    Parameters
    ----------
    matrix : (P, S) sparse matrix
    per_spring : (F, S, 3) ndarray

    Returns
    -------
    (F, P, 3) ndarray
    """
    n_frames, n_springs, _ = per_spring.shape
    flat = np.ascontiguousarray(per_spring.transpose(1, 0, 2)).reshape(n_springs, -1)
    out = matrix @ flat
    return np.ascontiguousarray(out.reshape(-1, n_frames, 3).transpose(1, 0, 2))


class MeshOperators:
    """Precomputed spring incidence of an ``n x n`` mesh (state: the sparse matrices)."""

    def __init__(self, n):
        self.n = n
        self.a, self.b, self.kind = springs(n)
        full = scatter_matrix(n).tocsc()
        self.by_type = [full[:, self.kind == t].tocsr() for t in range(N_TYPES)]
        self.type_slices = [np.flatnonzero(self.kind == t) for t in range(N_TYPES)]
        i, j = np.divmod(np.arange(n * n), n)
        self.s_i = 2.0 * i / (n - 1) - 1.0
        self.s_j = 2.0 * j / (n - 1) - 1.0


def spring_sums(ops, x):
    """Per-type sums ``A_t = sum +-d`` and ``B_t = sum +-d / L`` at each particle.

    The spring force of type ``t`` on the particles is ``k_t (A_t - l_t B_t)``.

    Parameters
    ----------
    ops : MeshOperators
    x : (F, P, 3) ndarray

    Returns
    -------
    A, B : (6, F, P, 3) ndarray
    """
    A = np.empty((N_TYPES,) + x.shape)
    B = np.empty_like(A)
    for t in range(N_TYPES):
        idx = ops.type_slices[t]
        d = x[:, ops.b[idx]] - x[:, ops.a[idx]]
        length = np.linalg.norm(d, axis=2, keepdims=True)
        A[t] = scatter(ops.by_type[t], d)
        B[t] = scatter(ops.by_type[t], d / np.maximum(length, 1e-300))
    return A, B


def spring_force(A, B, rest, k):
    """Spring forces ``sum_t k_t (A_t - l_t B_t)``, (F, P, 3), from :func:`spring_sums`.

    Parameters
    ----------
    A, B : (6, F, P, 3) ndarray
        Per-type sums of :func:`spring_sums`.
    rest, k : (6,) array_like
        Per-type rest lengths ``l_t`` and stiffnesses ``k_t``.
    """
    rest = np.asarray(rest, dtype=float)
    k = np.asarray(k, dtype=float)
    return np.einsum("t,tfpc->fpc", k, A) - np.einsum("t,tfpc->fpc", k * rest, B)


def dashpot_sums(ops, x, v):
    """Spring-axis relative velocity ``sum +-((v_b - v_a).u) u`` over all springs, (F, P, 3).

    Parameters
    ----------
    ops : MeshOperators
    x, v : (F, P, 3) ndarray
    """
    total = np.zeros_like(x)
    for t in range(N_TYPES):
        idx = ops.type_slices[t]
        d = x[:, ops.b[idx]] - x[:, ops.a[idx]]
        u = d / np.maximum(np.linalg.norm(d, axis=2, keepdims=True), 1e-300)
        rel = np.sum((v[:, ops.b[idx]] - v[:, ops.a[idx]]) * u, axis=2, keepdims=True)
        total += scatter(ops.by_type[t], rel * u)
    return total


def normals(x, n):
    """Unit surface normals from central differences on the grid (one-sided at borders).

    Parameters
    ----------
    x : (F, P, 3) ndarray
    n : int

    Returns
    -------
    (F, P, 3) ndarray of unit normals (sign fixed by the grid orientation).
    """
    grid = x.reshape(x.shape[0], n, n, 3)
    along_j = np.gradient(grid, axis=2)
    along_i = np.gradient(grid, axis=1)
    normal = np.cross(along_j, along_i)
    norm = np.linalg.norm(normal, axis=3, keepdims=True)
    return (normal / np.maximum(norm, 1e-300)).reshape(x.shape)


def area_normals(x, n):
    """Area-weighted normals: per particle, a third of the area vectors of its triangles.

    Every grid cell is split along its ``(i, j)-(i+1, j+1)`` diagonal into two triangles;
    the result's direction is the area-weighted normal and its length the particle's share
    of the surface (a third of its triangles' areas, less where the sheet is curved).

    Parameters
    ----------
    x : (F, P, 3) ndarray
    n : int

    Returns
    -------
    (F, P, 3) ndarray (same orientation as :func:`normals`).
    """
    grid = x.reshape(x.shape[0], n, n, 3)
    p00, p01 = grid[:, :-1, :-1], grid[:, :-1, 1:]
    p10, p11 = grid[:, 1:, :-1], grid[:, 1:, 1:]
    upper = 0.5 * np.cross(p01 - p00, p11 - p00) / 3.0   # triangle (i,j), (i,j+1), (i+1,j+1)
    lower = 0.5 * np.cross(p11 - p00, p10 - p00) / 3.0   # triangle (i,j), (i+1,j+1), (i+1,j)
    out = np.zeros_like(grid)
    out[:, :-1, :-1] += upper + lower
    out[:, :-1, 1:] += upper
    out[:, 1:, 1:] += upper + lower
    out[:, 1:, :-1] += lower
    return out.reshape(x.shape)
