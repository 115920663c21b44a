"""The effect library: physical forces, as plug-ins of the identification engine.

Each effect is linear in its coefficients ``theta`` once the base model is known: its
extra acceleration (under the data's nominal mass) is ``basis(frames) @ theta``, and the
extra force handed to :func:`replication.cloth.model.step` is the nominal mass times that.
An :class:`Effect` is a :class:`replication.cloth.regression.Plugin` (``name``, ``basis``,
``needs_base``), so base model and effects are fitted jointly by one engine.
``physical`` turns ``theta`` into the effect's own parameters and says where it acts.

Library: linear air damping, quadratic drag, Provot's normal fluid force (area-weighted
normals) with a wind velocity, constant body force, stiffness that differs by direction
(warp and weft), a mass profile over the sheet (per row and per column: gradients, steps,
bands) and spring (dashpot) damping.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from replication.cloth import geometry


def _linear_damping(q):
    return q.per_mass(-q.v)[..., None]


def _quadratic_drag(q):
    speed = np.linalg.norm(q.v, axis=2, keepdims=True)
    return q.per_mass(-speed * q.v)[..., None]


def _normal_fluid(q):
    # F = C A (n.(u - v)) n with N = A n the area-weighted normal: C (N.(u - v)) N / |N|
    area_normal = q.area_normals
    unit = area_normal / np.maximum(np.linalg.norm(area_normal, axis=2, keepdims=True),
                                    1e-300)
    normal_speed = np.sum(area_normal * q.v, axis=2, keepdims=True)
    columns = [q.per_mass(-normal_speed * unit)]
    columns += [q.per_mass(area_normal[..., c:c + 1] * unit) for c in range(3)]
    return np.stack(columns, axis=-1)


def _body_force(q):
    out = np.zeros(q.x.shape + (3,))
    for c in range(3):
        out[:, :, c, c] = 1.0 / q.mass[None, :]
    return out


def _anisotropic_stiffness(q):
    # extra stiffness of the springs along j (types 0, 4) and along i (types 1, 5)
    A, B = q.sums
    rest = q.rest
    along_j = A[0] - rest[0] * B[0] + A[4] - rest[4] * B[4]
    along_i = A[1] - rest[1] * B[1] + A[5] - rest[5] * B[5]
    return np.stack([q.per_mass(along_j), q.per_mass(along_i)], axis=-1)


def profile_indicators(n):
    """Centred row and column indicators, (P, 2 (n - 1)): column ``r < n-1`` is
    ``1[i = r] - 1/n``, then the same for ``j``. Centred, because a uniform change of the
    inverse mass is a change of every stiffness (not identifiable apart from K)."""
    i, j = np.divmod(np.arange(n * n), n)
    rows = (i[:, None] == np.arange(n - 1)[None, :]) - 1.0 / n
    cols = (j[:, None] == np.arange(n - 1)[None, :]) - 1.0 / n
    return np.hstack([rows, cols]).astype(float)


def _nonuniform_mass(q):
    # inverse mass (1 + beta_p) / m with beta_p = profile_row(i) + profile_col(j)
    inner = q.per_mass(q.inner_force)
    return inner[..., None] * profile_indicators(q.ops.n)[None, :, None, :]


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
    k_j, k_i = K + float(theta[0]), K + float(theta[1])
    return {"k_along_j": k_j, "k_along_i": k_i, "ratio_j_over_i": k_j / k_i,
            "where": "springs along j (types 0, 4) vs along i (types 1, 5)"}


def inverse_mass_map(theta, n):
    """Relative inverse mass ``m / m_p = 1 + row(i) + col(j)`` per particle, (n, n), from
    the profile coefficients (0 or less: no mass gives it)."""
    return (1.0 + profile_indicators(n) @ np.asarray(theta, dtype=float)).reshape(n, n)


def _profile_side(size):
    """The mesh side ``n`` of a mass profile with ``size = 2 (n - 1)`` coefficients."""
    return size // 2 + 1


def _mass_physical(theta, base, *, threshold=0.1):
    n = _profile_side(len(theta))
    inverse = inverse_mass_map(theta, n)
    relative = 1.0 / np.maximum(inverse, 1e-6)   # m_p / m
    rows = relative.mean(axis=1)
    cols = relative.mean(axis=0)
    return {"relative_mass": relative.round(4).tolist(),
            "rows_differing": [int(r) for r in np.flatnonzero(np.abs(rows / np.median(rows)
                                                                      - 1) > threshold)],
            "columns_differing": [int(c) for c in np.flatnonzero(np.abs(cols / np.median(cols)
                                                                         - 1) > threshold)],
            "where": f"rows and columns whose mean relative mass differs from the median by "
                     f"more than {threshold:.0%} (mass relative to the file's, up to a common "
                     "factor that is not identifiable apart from K)",
            # no mass: 1 + row(i) + col(j) <= 0 (relative_mass shows 1e6 there)
            "nonpositive_inverse_mass": int(np.count_nonzero(inverse <= 0.0))}


class Effect(NamedTuple):
    """One library entry, a :class:`~replication.cloth.regression.Plugin` of the engine.

    ``basis(q) -> (F, P, 3, m)`` extra acceleration per unit coefficient; ``physical(theta,
    base) -> dict``; ``nonnegative`` : coefficient indices that must be >= 0 for the force
    to be physical (one-sided tests); ``needs_base``: columns depend on the base model.
    """

    name: str
    coefficients: tuple
    basis: Callable
    physical: Callable
    nonnegative: tuple
    description: str
    needs_base: bool = False


def _profile_names(n=17):
    return tuple(f"row{r}" for r in range(n - 1)) + tuple(f"col{c}" for c in range(n - 1))


def coefficient_names(effect, size):
    """The names of the ``size`` coefficients ``effect`` has on a mesh: a mass profile has
    ``2 (n - 1)`` of them on an ``n x n`` mesh (``row0..``, ``col0..``; the library entry
    lists the 17 x 17 contract's), every other effect its fixed ``coefficients``."""
    if effect.name == "nonuniform_mass":
        return _profile_names(_profile_side(size))
    return effect.coefficients


LIBRARY = {
    effect.name: effect for effect in (
        Effect("linear_damping", ("c",), _linear_damping, _scalar("c"), (0,),
               "air damping F = -c v"),
        Effect("quadratic_drag", ("c_q",), _quadratic_drag, _scalar("c_q"), (0,),
               "quadratic drag F = -c_q |v| v"),
        Effect("normal_fluid", ("C", "C*u_x", "C*u_y", "C*u_z"), _normal_fluid,
               _fluid_physical, (0,),
               "Provot's fluid force F = C A (n.(u - v)) n, area-weighted normals, wind u"),
        Effect("body_force", ("f_x", "f_y", "f_z"), _body_force,
               lambda theta, base: {"f": [float(t) for t in theta]}, (),
               "constant body force F = f"),
        Effect("anisotropic_stiffness", ("dk_j", "dk_i"), _anisotropic_stiffness,
               _anisotropy_physical, (),
               "stiffness by direction: k = K + dk_j along j (types 0, 4), K + dk_i along i "
               "(types 1, 5)", True),
        Effect("nonuniform_mass", _profile_names(), _nonuniform_mass, _mass_physical, (),
               "mass profile: inverse mass (1 + row(i) + col(j)) / m per particle "
               "(gradients, steps, bands)", True),
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
