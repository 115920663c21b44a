"""The effect library: physical forces with few parameters, as plug-ins of the cloth step.

Each effect is linear in a few coefficients ``theta`` once the base model is known: its
extra acceleration (under the data's nominal mass) is ``basis(frames) @ theta``, and the
extra force handed to :func:`replication.cloth.model.step` is the nominal mass times that.
``physical`` turns ``theta`` into the effect's own parameters.

Library (issue 6): linear air damping, quadratic drag, Provot's normal fluid force with a
wind velocity, constant body force, anisotropic stiffness (warp and weft differ),
non-uniform mass (inverse mass linear over the sheet) and spring (dashpot) damping.
"""

from __future__ import annotations

from functools import cached_property
from typing import Callable, NamedTuple

import numpy as np

from replication.discrepancy import geometry


class Frames:
    """States ``(x, v)`` of some frames with the quantities effects are built from.

    Parameters
    ----------
    x, v : (F, P, 3) ndarray
    ops : geometry.MeshOperators
    mass : (P,) ndarray
        Nominal (file) mass per particle.
    rest, k : (6,) ndarray
        Current base-model rest lengths and stiffnesses (for terms built on spring forces).
    damping : float
        Known linear damping of the data file.
    """

    def __init__(self, x, v, ops, mass, rest, k, damping=0.0):
        self.x = x
        self.v = v
        self.ops = ops
        self.mass = mass
        self.rest = np.asarray(rest, dtype=float)
        self.k = np.asarray(k, dtype=float)
        self.damping = float(damping)

    @cached_property
    def sums(self):
        return geometry.spring_sums(self.ops, self.x)

    @cached_property
    def normals(self):
        return geometry.normals(self.x, self.ops.n)

    @cached_property
    def inner_force(self):
        """Spring forces plus known damping at the base parameters, (F, P, 3)."""
        A, B = self.sums
        return geometry.spring_force(A, B, self.rest, self.k) - self.damping * self.v

    def per_mass(self, force):
        return force / self.mass[None, :, None]


def _linear_damping(q):
    return q.per_mass(-q.v)[..., None]


def _quadratic_drag(q):
    speed = np.linalg.norm(q.v, axis=2, keepdims=True)
    return q.per_mass(-speed * q.v)[..., None]


def _normal_fluid(q):
    nrm = q.normals
    normal_speed = np.sum(nrm * q.v, axis=2, keepdims=True)
    columns = [q.per_mass(-normal_speed * nrm)]
    columns += [q.per_mass(nrm[..., c:c + 1] * nrm) for c in range(3)]
    return np.stack(columns, axis=-1)


def _body_force(q):
    out = np.zeros(q.x.shape + (3,))
    for c in range(3):
        out[:, :, c, c] = 1.0 / q.mass[None, :]
    return out


def _anisotropic_stiffness(q):
    A, B = q.sums
    rest = q.rest
    warp = A[0] - rest[0] * B[0] + A[4] - rest[4] * B[4]
    weft = A[1] - rest[1] * B[1] + A[5] - rest[5] * B[5]
    return q.per_mass(warp - weft)[..., None]


def _nonuniform_mass(q):
    inner = q.per_mass(q.inner_force)
    return np.stack([q.ops.s_i[None, :, None] * inner, q.ops.s_j[None, :, None] * inner],
                    axis=-1)


def _spring_damping(q):
    return q.per_mass(geometry.dashpot_sums(q.ops, q.x, q.v))[..., None]


def _scalar(name):
    return lambda theta, base: {name: float(theta[0])}


def _fluid_physical(theta, base):
    C = float(theta[0])
    wind = (np.asarray(theta[1:4]) / C).tolist() if C != 0 else [0.0, 0.0, 0.0]
    return {"C": C, "wind": wind}


def _anisotropy_physical(theta, base):
    K = float(np.mean(base["k"]))
    return {"a": float(theta[0]) / K}


class Effect(NamedTuple):
    """One library entry.

    ``basis(q) -> (F, P, 3, m)`` extra acceleration per unit coefficient; ``physical(theta,
    base) -> dict``; ``nonnegative`` : coefficient indices that must be >= 0 for the force
    to be physical (one-sided tests); ``groups`` : physical keys compared to the truth.
    """

    name: str
    coefficients: tuple
    basis: Callable
    physical: Callable
    nonnegative: tuple
    description: str


LIBRARY = {
    effect.name: effect for effect in (
        Effect("linear_damping", ("c",), _linear_damping, _scalar("c"), (0,),
               "air damping F = -c v"),
        Effect("quadratic_drag", ("c_q",), _quadratic_drag, _scalar("c_q"), (0,),
               "quadratic drag F = -c_q |v| v"),
        Effect("normal_fluid", ("C", "C*u_x", "C*u_y", "C*u_z"), _normal_fluid,
               _fluid_physical, (0,),
               "Provot's fluid force F = C (n.(u - v)) n with wind velocity u"),
        Effect("body_force", ("f_x", "f_y", "f_z"), _body_force,
               lambda theta, base: {"f": [float(t) for t in theta]}, (),
               "constant body force F = f"),
        Effect("anisotropic_stiffness", ("K*a",), _anisotropic_stiffness,
               _anisotropy_physical, (),
               "warp/weft stiffness k_j = K (1 + a), k_i = K (1 - a) (types 0,4 vs 1,5)"),
        Effect("nonuniform_mass", ("beta_i", "beta_j"), _nonuniform_mass,
               lambda theta, base: {"beta_i": float(theta[0]), "beta_j": float(theta[1])},
               (), "inverse mass linear over the sheet: m / m_p = 1 + beta_i s_i + beta_j s_j"),
        Effect("spring_damping", ("c_s",), _spring_damping, _scalar("c_s"), (0,),
               "dashpot along every spring F_a = c_s ((v_b - v_a).u) u"),
    )
}
EFFECT_NAMES = tuple(LIBRARY)


def get_effect(name):
    """The library entry called ``name`` (ValueError naming the choices otherwise)."""
    if name not in LIBRARY:
        raise ValueError(f"effect {name!r} is not in the library; expected one of "
                         + ", ".join(EFFECT_NAMES))
    return LIBRARY[name]


def extra_force(terms, q):
    """Total extra force of fitted effect terms on the frames ``q``.

    Parameters
    ----------
    terms : list of (name, theta)
    q : Frames

    Returns
    -------
    (F, P, 3) ndarray (zeros when ``terms`` is empty)
    """
    total = np.zeros_like(q.x)
    for name, theta in terms:
        total += get_effect(name).basis(q) @ np.asarray(theta, dtype=float)
    return total * q.mass[None, :, None]
