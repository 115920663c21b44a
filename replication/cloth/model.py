"""The cloth model of docs/cloth-model.md: immutable scene and parameters, pure step.

State is ``(x, v)`` with a leading population axis, shapes ``(pop, n*n, 3)``, flat
particle index ``p = i*n + j``. Parameters are per spring type, shapes ``(pop, 6)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from replication.cloth import kernels
from replication.errors import InputError
from replication.cloth.mesh import (
    DEFAULT_N, DEFAULT_SIDE, FAMILY_OF_TYPE, N_TYPES, flat_rest_positions,
    reference_rest_lengths, spacing, springs,
)

CONTRACT_DT = 0.002
CONTRACT_MASS = 0.001
CONTRACT_GRAVITY = (0.0, 0.0, -9.81)

PARAM_NAMES_5 = ("l01", "l23", "l45", "K", "tau")
PARAM_NAMES_18 = tuple(
    f"{group}{t}" for group in ("rest", "k", "tau") for t in range(N_TYPES)
)


@dataclass(frozen=True)
class Scene:
    """What the model is told and never identifies: mesh, masses, pins, gravity, time step."""

    n: int
    dt: float
    mass: np.ndarray          # (P,)
    gravity: np.ndarray       # (3,)
    damping: float
    pinned: np.ndarray        # (k, 2) int, (i, j)
    spring_a: np.ndarray      # (S,)
    spring_b: np.ndarray      # (S,)
    spring_type: np.ndarray   # (S,)
    free: np.ndarray          # (P,) bool

    @property
    def n_particles(self):
        return self.n * self.n

    @property
    def n_springs(self):
        return int(self.spring_a.size)

    def kernel_args(self):
        """Arguments shared by every kernel call, in the kernels' order."""
        return (self.spring_a, self.spring_b, self.spring_type, self.free, self.mass,
                self.gravity, float(self.damping), float(self.dt))


def make_scene(n=DEFAULT_N, *, dt=CONTRACT_DT, mass=CONTRACT_MASS, gravity=CONTRACT_GRAVITY,
               damping=0.0, pinned=None):
    """Build a :class:`Scene`; defaults are the contract's.

    Parameters
    ----------
    n : int
        Particles per side (``n x n`` sheet).
    dt : float
        Time step.
    mass : float or (n, n) array_like
    gravity : (3,) array_like
    damping : float
        Linear damping ``c`` (0 in the contract).
    pinned : (k, 2) array_like, optional
        ``(i, j)`` of pinned particles; default the contract's two top corners.
    """
    if pinned is None:
        pinned = ((0, 0), (0, n - 1))
    pinned = np.asarray(pinned, dtype=np.int64).reshape(-1, 2)
    outside = np.any((pinned < 0) | (pinned >= n), axis=1)
    if np.any(outside):
        i, j = pinned[outside][0]
        raise InputError(f"pinned: ({i}, {j}) is outside the {n}x{n} mesh; expected "
                         f"(i, j) in 0..{n - 1} (null: the top corners (0, 0), (0, {n - 1}))")
    mass = np.broadcast_to(np.asarray(mass, dtype=float), (n, n)).reshape(n * n).copy()
    free = np.ones(n * n, dtype=np.bool_)
    free[pinned[:, 0] * n + pinned[:, 1]] = False
    a, b, kind = springs(n)
    return Scene(n=n, dt=float(dt), mass=mass, gravity=np.asarray(gravity, dtype=float),
                 damping=float(damping), pinned=pinned, spring_a=a, spring_b=b,
                 spring_type=kind, free=free)


class ClothParams(NamedTuple):
    """Per-type rest length, stiffness and critical elongation rate, each ``(pop, 6)``."""

    rest: np.ndarray
    k: np.ndarray
    tau: np.ndarray

    @property
    def pop(self):
        return self.rest.shape[0]


_K_COLUMNS = np.full(N_TYPES, 3)     # column of K in a 5-parameter row, once per type
_TAU_COLUMNS = np.full(N_TYPES, 4)   # column of tau


def params_from_vectors(X):
    """Parameter vectors to :class:`ClothParams`.

    Parameters
    ----------
    X : (pop, 5) or (pop, 18) array_like
        5-parameter rows ``(l01, l23, l45, K, tau)`` or 18-parameter rows
        ``(rest_0..5, k_0..5, tau_0..5)``. A single row may be given as ``(5,)``/``(18,)``.
    """
    X = np.atleast_2d(np.asarray(X, dtype=float))
    if X.shape[1] == 5:
        rest = X[:, FAMILY_OF_TYPE]                  # columns 0-2 are the families
        k = X[:, _K_COLUMNS]
        tau = X[:, _TAU_COLUMNS]
    elif X.shape[1] == 18:
        rest, k, tau = X[:, 0:6], X[:, 6:12], X[:, 12:18]
    else:
        raise ValueError(f"parameter vectors have {X.shape[1]} columns; expected 5 or 18")
    return ClothParams(np.ascontiguousarray(rest), np.ascontiguousarray(k),
                       np.ascontiguousarray(tau))


def reference_vector(tau, *, K=4.0, n=DEFAULT_N, side=DEFAULT_SIDE):
    """The contract's 5-parameter reference ``(h, h*sqrt 2, 2h, K, tau)``.

    Parameters
    ----------
    tau : float
    K : float
    n : int
    side : float
        Side of the sheet; ``h = side / (n - 1)``.

    Returns
    -------
    (5,) ndarray
    """
    return np.concatenate([reference_rest_lengths(spacing(n, side)), [K, tau]])


def initial_state(scene, pop=1, side=DEFAULT_SIDE):
    """The flat initial sheet at rest, repeated ``pop`` times: ``x, v`` of (pop, P, 3).

    Parameters
    ----------
    scene : Scene
    pop : int
        Copies (population size).
    side : float
    """
    x0 = flat_rest_positions(scene.n, side)
    x = np.repeat(x0[None], pop, axis=0)
    return x, np.zeros_like(x)


def _population_arrays(x, v, params):
    x = np.ascontiguousarray(x, dtype=float)
    v = np.ascontiguousarray(v, dtype=float)
    if x.ndim != 3 or x.shape != v.shape or x.shape[0] != params.pop:
        raise ValueError(
            f"state shapes x{x.shape}, v{v.shape} do not match a population of {params.pop}: "
            "expected (pop, n*n, 3) each"
        )
    return x, v


def step(x, v, params, scene, extra_force=None):
    """One time step for each member of the population (pure: inputs are not modified).

    Parameters
    ----------
    x, v : (pop, n*n, 3) ndarray
    params : ClothParams with arrays of shape (pop, 6)
    scene : Scene
    extra_force : (pop, n*n, 3) ndarray, optional
        Forces added to gravity, damping and springs before integration (effect plug-ins
        of the discrepancy workflow); applied to free particles only.

    Returns
    -------
    x_next, v_next : (pop, n*n, 3) ndarray
    """
    x, v = _population_arrays(x, v, params)
    if extra_force is None:
        extra_force = np.zeros_like(x)
    extra_force = np.ascontiguousarray(np.broadcast_to(extra_force, x.shape), dtype=float)
    return kernels.step_batch(x, v, params.rest, params.k, params.tau, extra_force,
                              *scene.kernel_args())


def simulate(params, scene, n_steps, x0=None, v0=None):
    """Roll the model out for ``n_steps`` steps.

    Parameters
    ----------
    params : ClothParams
        ``(pop, 6)`` rest lengths, stiffnesses and taus (:func:`params_from_vectors`).
    scene : Scene
    n_steps : int
    x0, v0 : (pop or 1, n*n, 3) ndarray, optional
        Initial state; default the flat sheet at rest (:func:`initial_state`).

    Returns
    -------
    positions, velocities : (pop, n_steps + 1, n*n, 3) ndarray, frame 0 the initial state.
    """
    if x0 is None:
        x0, v0 = initial_state(scene, params.pop)
    x0, v0 = _population_arrays(x0, v0, params)
    return kernels.rollout_batch(x0, v0, params.rest, params.k, params.tau, int(n_steps),
                                 *scene.kernel_args())
