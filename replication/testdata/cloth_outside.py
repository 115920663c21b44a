"""Cloth trajectories with hidden physical effects, for blind tests of the discrepancy workflow.

This module is deliberately independent of the rest of the project: it imports only numpy
and the standard library's ``json`` and ``math``. The cloth model is re-implemented from the
text of the contract (docs/cloth-model.md) and every hidden effect is written from its
physical definition, so that a bug shared by the project's simulator and its effect library
cannot hide itself in the test data.

Conventions (the contract's): ``n = 17`` particles per side, flat index ``p = i*n + j``,
spacing ``h = 1.5/16``, initial flat sheet ``x = (j*h, i*h, 0)`` at rest, pinned corners
``(0, 0)`` and ``(0, 16)``, ``dt = 0.002``, nominal mass ``0.001`` per particle, gravity
``(0, 0, -9.81)``; semi-implicit Euler with one Jacobi pass of Provot's deformation constraint.

A *spec* is a JSON-able dict::

    {"n_frames": int, "K": float, "tau": float, "noise_h": float, "seed": int,
     "effects": [{"kind": str, **parameters}, ...]}      # 0, 1 or 2 effects, distinct kinds

:func:`draw_spec` draws one at random, :func:`simulate` runs it without noise, :func:`make`
returns the trajectory file's arrays plus the ground truth, :func:`write_npz` writes the file
(without the truth).
"""

import json
import math

import numpy as np

# ---------------------------------------------------------------------------------------------
# The contract's scene
# ---------------------------------------------------------------------------------------------
N = 17                          # particles per side
SIDE = 1.5                      # side length of the sheet (m)
H = SIDE / (N - 1)              # grid spacing = structural rest length (m)
N_PARTICLES = N * N
DT = 0.002                      # time step = time between frames (s)
MASS = 0.001                    # nominal mass per particle (kg), what the file says
GRAVITY = np.array([0.0, 0.0, -9.81])
PINNED = ((0, 0), (0, N - 1))   # (i, j) of the two pinned corners

# The six spring types of the contract's table as (a, b) offsets from particle (i, j).
_SPRING_OFFSETS = (
    ((0, 0), (0, 1)),   # 0: structural along j
    ((0, 0), (1, 0)),   # 1: structural along i
    ((0, 0), (1, 1)),   # 2: shear
    ((0, 1), (1, 0)),   # 3: shear, the other diagonal
    ((0, 0), (0, 2)),   # 4: flexion along j
    ((0, 0), (2, 0)),   # 5: flexion along i
)
# rest length of each type in the 5-parameter model at its reference values
_REST_OF_TYPE = np.array([H, H, H * math.sqrt(2.0), H * math.sqrt(2.0), 2.0 * H, 2.0 * H])


def _build_springs():
    """Springs of the 17x17 mesh from the contract's table.

    Returns
    -------
    a, b : (S,) int ndarray
        Flat indices of the two ends, ``d = x_b - x_a``.
    kind : (S,) int ndarray
        Spring type 0..5.
    """
    i, j = np.meshgrid(np.arange(N), np.arange(N), indexing="ij")
    ends_a, ends_b, kinds = [], [], []
    for t, ((ai, aj), (bi, bj)) in enumerate(_SPRING_OFFSETS):
        reach_i = max(ai, bi)
        reach_j = max(aj, bj)
        inside = (i + reach_i < N) & (j + reach_j < N)     # both ends on the mesh
        ii, jj = i[inside], j[inside]
        ends_a.append((ii + ai) * N + (jj + aj))
        ends_b.append((ii + bi) * N + (jj + bj))
        kinds.append(np.full(ii.size, t))
    return np.concatenate(ends_a), np.concatenate(ends_b), np.concatenate(kinds)


SPRING_A, SPRING_B, SPRING_TYPE = _build_springs()
SPRING_REST = _REST_OF_TYPE[SPRING_TYPE]
FREE = np.ones(N_PARTICLES, dtype=bool)
for _i, _j in PINNED:
    FREE[_i * N + _j] = False
# the pivot line of "swirl": the vertical through the midpoint of the two pins, which is the
# centre line of the sheet once it hangs
SWIRL_CENTER = (0.5 * (PINNED[0][1] + PINNED[1][1]) * H, 0.5 * (PINNED[0][0] + PINNED[1][0]) * H)

# ---------------------------------------------------------------------------------------------
# Catalogue of hidden effects
# ---------------------------------------------------------------------------------------------
KINDS = {
    "air_damping": {
        "expected": "linear_damping",
        "description": "linear air damping F = -c v on every free particle; c in kg/s",
    },
    "quadratic_drag": {
        "expected": "quadratic_drag",
        "description": "quadratic drag F = -c_q |v| v; c_q in kg/m",
    },
    "wind": {
        "expected": "normal_fluid",
        "description": "Provot's fluid force F_p = C A_p (n_p.(u - v_p)) n_p with area-weighted "
                       "vertex normals of the triangulated mesh and A_p one third of the "
                       "adjacent triangle areas; C in kg/(m^2 s), wind velocity u in m/s",
    },
    "constant_force": {
        "expected": "body_force",
        "description": "steady uniform force per unit mass a*e (a push or a tilt of gravity); "
                       "a in m/s^2, e a unit vector with a horizontal part",
    },
    "stiffness_direction": {
        "expected": "anisotropic_stiffness",
        "description": "springs along j (types 0 and 4) have stiffness K*r, along i (1, 5) and "
                       "shear K",
    },
    "mass_step": {
        "expected": "nonuniform_mass",
        "description": "mass 0.001*(1+s) in a band of rows at the bottom or of columns at one "
                       "side; the file still says 0.001",
    },
    "mass_gradient": {
        "expected": "nonuniform_mass",
        "description": "mass 0.001*(1 + g w), w in [0, 1] linear across the sheet along a "
                       "direction of the (i, j) plane; the file still says 0.001",
    },
    "spring_damping": {
        "expected": "spring_damping",
        "description": "dashpot along every spring F_a = c_s ((v_b - v_a).u) u, F_b = -F_a; "
                       "c_s in kg/s",
    },
    "gust": {
        "expected": "unexplained",
        "description": "uniform force per unit mass oscillating in time, "
                       "A sin(2 pi f t + phi) e, zero mean; A in m/s^2, f in Hz, t = frame "
                       "index * dt of the step's state",
    },
    "swirl": {
        "expected": "unexplained",
        "description": "horizontal force field rotating about the vertical line through the "
                       "midpoint of the pins, F = m s (-(y - yc), x - xc, 0); s in 1/s^2",
    },
    "cubic_springs": {
        "expected": "unexplained",
        "description": "stiffening springs, force k (L - l) (1 + b ((L - l)/l)^2) along d",
    },
}

# Nominal magnitude of each kind (the drawn one is NOMINAL * 10**u, u uniform in size_decades),
# with the parameter it sets. Physically moderate (about a tenth of gravity's pull on the moving
# sheet, or a 10 % change of a mass or a stiffness) and, for a 300-frame run with the median
# noise (7e-4 h), roughly comparable detectability: truth["snr"] ~ 3..10 at nominal size, so
# u = -1 is at or below the noise and u = +1 far above it.
NOMINAL = {
    "air_damping": 3e-4,          # c (kg/s): decay rate c/m = 0.3 1/s
    "quadratic_drag": 1e-4,       # c_q (kg/m): 0.1 m/s^2 at 1 m/s
    "wind": 0.05,                 # C (kg/(m^2 s)): ~0.7 m/s^2 on a face-on particle at 1.5 m/s
    "constant_force": 1.0,        # a (m/s^2): like a tilt of gravity by ~6 degrees
    "stiffness_direction": 0.1 * math.log(2.0),   # |ln r|: r = 1.07, at most 2 by default
    "mass_step": 0.1,             # s: 10 % more mass in the band, at most 2x by default
    "mass_gradient": 0.1,         # g: 10 % between the extremes, at most 2x by default
    "spring_damping": 3e-3,       # c_s (kg/s): relative decay rate c_s/m = 3 1/s
    "gust": 1.5,                  # A (m/s^2): rms 1 m/s^2
    "swirl": 1.0,                 # |s| (1/s^2): 0.75 m/s^2 at the sheet's edges
    "cubic_springs": 1.0,         # b: +1 % of spring force at 10 % strain, +25 % at 50 %
}
# the parameter each magnitude sets, and the cap that keeps mass and stiffness within 2x
MAGNITUDE_KEY = {
    "air_damping": "c", "quadratic_drag": "c_q", "wind": "C", "constant_force": "a",
    "stiffness_direction": "r", "mass_step": "s", "mass_gradient": "g",
    "spring_damping": "c_s", "gust": "A", "swirl": "s", "cubic_springs": "b",
}
_CAP = {"stiffness_direction": math.log(2.0), "mass_step": 1.0, "mass_gradient": 1.0}


# ---------------------------------------------------------------------------------------------
# Drawing a spec
# ---------------------------------------------------------------------------------------------
def _direction(rng, min_horizontal=0.5):
    """A random unit vector, uniform on the sphere among those whose horizontal (x, y) part
    has norm at least ``min_horizontal``; returns a list of 3 floats."""
    while True:
        e = rng.standard_normal(3)
        e /= np.linalg.norm(e)
        if math.hypot(e[0], e[1]) >= min_horizontal:
            return [float(c) for c in e]


def _draw_effect(rng, kind, size_decades):
    """Parameters of one effect of ``kind`` with magnitude ``NOMINAL * 10**u``."""
    u = rng.uniform(*size_decades)
    size = NOMINAL[kind] * 10.0 ** u
    if kind in _CAP:
        size = min(size, _CAP[kind])
    effect = {"kind": kind}
    if kind in ("air_damping", "quadratic_drag", "spring_damping", "cubic_springs"):
        effect[MAGNITUDE_KEY[kind]] = float(size)
    elif kind == "wind":
        speed = rng.uniform(0.5, 3.0)
        effect["C"] = float(size)
        effect["velocity"] = [float(speed * c) for c in _direction(rng)]
    elif kind == "constant_force":
        effect["a"] = float(size)
        effect["direction"] = _direction(rng)
    elif kind == "stiffness_direction":
        sign = 1.0 if rng.random() < 0.5 else -1.0
        effect["r"] = float(math.exp(sign * size))
    elif kind == "mass_step":
        effect["s"] = float(size)
        first = int(rng.integers(10, 16))           # the band is 2..7 rows/columns wide
        axis = "i" if rng.random() < 0.5 else "j"
        if axis == "i":                               # rows at the bottom (far from the pins)
            band = [first, N - 1]
        elif rng.random() < 0.5:                      # columns at one side or the other
            band = [first, N - 1]
        else:
            band = [0, N - 1 - first]
        effect["axis"] = axis
        effect["band"] = band
    elif kind == "mass_gradient":
        effect["g"] = float(size)
        effect["angle"] = float(rng.uniform(0.0, 2.0 * math.pi))
    elif kind == "gust":
        effect["A"] = float(size)
        effect["f"] = float(rng.uniform(2.0, 10.0))
        effect["phase"] = float(rng.uniform(0.0, 2.0 * math.pi))
        effect["direction"] = _direction(rng)
    elif kind == "swirl":
        sign = 1.0 if rng.random() < 0.5 else -1.0
        effect["s"] = float(sign * size)
        effect["center"] = [float(c) for c in SWIRL_CENTER]
    else:
        raise ValueError(f"unknown effect kind {kind!r}; expected one of {sorted(KINDS)}")
    return effect


def draw_spec(rng, *, kinds=None, n_effects=None, noise_h=None, frames_range=(100, 500),
              K_range=(2.5, 5.5), tau_range=(0.1, 0.6), size_decades=(-1.0, 1.0)):
    """Draw a random spec.

    Parameters
    ----------
    rng : numpy.random.Generator or int
        Source of randomness (an int is used as a seed).
    kinds : sequence of str, optional
        Kinds to draw from, uniformly (default: all of :data:`KINDS`).
    n_effects : {0, 1, 2}, optional
        Number of effects; default drawn with probabilities (0.25, 0.5, 0.25), capped at the
        number of kinds available. Two effects are always of different kinds.
    noise_h : float, optional
        Position noise sd in units of ``h``; default 0 with probability 0.2, else log-uniform
        in [1e-4, 5e-3].
    frames_range : (int, int)
        Inclusive range of the number of frames.
    K_range, tau_range : (float, float)
        Uniform ranges of the stiffness ``K`` and critical elongation rate ``tau``.
    size_decades : (float, float)
        Effect magnitudes are ``NOMINAL[kind] * 10**u`` with ``u`` uniform in this range
        (mass and stiffness changes capped at 2x).

    Returns
    -------
    dict
        JSON-able spec (see the module docstring).
    """
    if not isinstance(rng, np.random.Generator):
        rng = np.random.default_rng(rng)
    kinds = sorted(KINDS) if kinds is None else list(kinds)
    unknown = [kind for kind in kinds if kind not in KINDS]
    if unknown or len(set(kinds)) != len(kinds):
        raise ValueError(f"kinds {kinds}: expected distinct names among {sorted(KINDS)}")
    if n_effects is None:
        n_effects = min(int(rng.choice(3, p=[0.25, 0.5, 0.25])), len(kinds))
    elif not 0 <= n_effects <= min(2, len(kinds)):
        raise ValueError(f"n_effects={n_effects}: expected 0..{min(2, len(kinds))}")
    if noise_h is None:
        noise_h = 0.0 if rng.random() < 0.2 else math.exp(rng.uniform(math.log(1e-4),
                                                                      math.log(5e-3)))
    n_frames = int(rng.integers(frames_range[0], frames_range[1] + 1))
    K = float(rng.uniform(*K_range))
    tau = float(rng.uniform(*tau_range))
    chosen = rng.choice(len(kinds), size=n_effects, replace=False) if n_effects else []
    effects = [_draw_effect(rng, kinds[int(c)], size_decades) for c in chosen]
    return {"n_frames": n_frames, "K": K, "tau": tau, "noise_h": float(noise_h),
            "seed": int(rng.integers(2**31 - 1)), "effects": effects}


# ---------------------------------------------------------------------------------------------
# The model: forces and one time step
# ---------------------------------------------------------------------------------------------
def _scatter(index, weights):
    """Sum per-spring (S, 3) ``weights`` onto particles ``index`` (S,): (P, 3)."""
    slots = (3 * index[:, None] + np.arange(3)).ravel()        # (particle, component) slots
    return np.bincount(slots, weights=weights.ravel(), minlength=3 * N_PARTICLES).reshape(-1, 3)


def _particle_mass(effects):
    """True mass per particle, (P,): the nominal 0.001 changed by the mass effects."""
    mass = np.full((N, N), MASS)
    i, j = np.meshgrid(np.arange(N), np.arange(N), indexing="ij")
    for effect in effects:
        if effect["kind"] == "mass_step":
            lo, hi = effect["band"]
            line = i if effect["axis"] == "i" else j
            mass = np.where((line >= lo) & (line <= hi), mass * (1.0 + effect["s"]), mass)
        elif effect["kind"] == "mass_gradient":
            # linear in the projection of (i, j) on the direction, scaled to [0, 1] over the sheet
            proj = i * math.cos(effect["angle"]) + j * math.sin(effect["angle"])
            w = (proj - proj.min()) / (proj.max() - proj.min())
            mass = mass * (1.0 + effect["g"] * w)
    return mass.reshape(N_PARTICLES)


def _model(spec, chosen):
    """Everything the force evaluation needs for ``spec``'s K and tau with the effects whose
    indices in ``spec["effects"]`` are listed in ``chosen``.

    The keys ``springs`` and ``masses`` name which effects change the springs and the masses,
    so that a step can share the pieces that models with the same springs or masses have in
    common.
    """
    effects = [spec["effects"][e] for e in chosen]
    k = np.full(SPRING_TYPE.size, float(spec["K"]))
    model = {"effects": spec["effects"], "mass": _particle_mass(effects), "k": k,
             "cubic_b": 0.0, "dashpot": 0.0,
             "fields": [e for e in chosen if spec["effects"][e]["kind"] in _FIELDS],
             "springs": tuple(e for e in chosen if spec["effects"][e]["kind"] in _SPRING_KINDS),
             "masses": tuple(e for e in chosen if spec["effects"][e]["kind"] in _MASS_KINDS)}
    for effect in effects:
        if effect["kind"] == "stiffness_direction":
            along_j = (SPRING_TYPE == 0) | (SPRING_TYPE == 4)
            k[along_j] = spec["K"] * effect["r"]
        elif effect["kind"] == "cubic_springs":
            model["cubic_b"] = float(effect["b"])
        elif effect["kind"] == "spring_damping":
            model["dashpot"] = float(effect["c_s"])
    return model


def _air_damping(x, v, t, mass, effect):
    """Linear air resistance F = -c v."""
    return -effect["c"] * v


def _quadratic_drag(x, v, t, mass, effect):
    """Quadratic drag F = -c_q |v| v (opposes the motion, grows with speed squared)."""
    speed = np.linalg.norm(v, axis=1, keepdims=True)
    return -effect["c_q"] * speed * v


def _cross(u, w):
    """Cross product over the last axis (size 3)."""
    return np.stack([u[..., 1] * w[..., 2] - u[..., 2] * w[..., 1],
                     u[..., 2] * w[..., 0] - u[..., 0] * w[..., 2],
                     u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]], axis=-1)


def _vertex_normals_and_areas(x):
    """Area-weighted unit normals and lumped areas of the triangulated sheet.

    Every grid cell ``(i, j)-(i+1, j+1)`` is split along its diagonal ``(i, j)-(i+1, j+1)`` into
    triangles ``(i,j), (i,j+1), (i+1,j+1)`` and ``(i,j), (i+1,j+1), (i+1,j)`` (both oriented +z
    on the flat sheet). A particle's normal is the unit vector of the sum of its adjacent
    triangles' area-weighted normals; its area is one third of theirs.

    Parameters
    ----------
    x : (P, 3) ndarray

    Returns
    -------
    normals : (P, 3) ndarray, unit (zero where the adjacent triangles are degenerate)
    areas : (P,) ndarray
    """
    g = x.reshape(N, N, 3)
    p00, p01, p10, p11 = g[:-1, :-1], g[:-1, 1:], g[1:, :-1], g[1:, 1:]
    # cross product of two edges = 2 * area * unit normal of the triangle
    c1 = _cross(p01 - p00, p11 - p00)
    c2 = _cross(p11 - p00, p10 - p00)
    a1 = 0.5 * np.sqrt(np.einsum("...c,...c->...", c1, c1))
    a2 = 0.5 * np.sqrt(np.einsum("...c,...c->...", c2, c2))
    weighted = np.zeros((N, N, 3))
    area = np.zeros((N, N))
    # triangle 1 touches 00, 01, 11; triangle 2 touches 00, 11, 10
    for (si, sj), tris in (((slice(None, -1), slice(None, -1)), ((c1, a1), (c2, a2))),
                           ((slice(None, -1), slice(1, None)), ((c1, a1),)),
                           ((slice(1, None), slice(1, None)), ((c1, a1), (c2, a2))),
                           ((slice(1, None), slice(None, -1)), ((c2, a2),))):
        for cross, tri_area in tris:
            weighted[si, sj] += 0.5 * cross      # area * unit normal
            area[si, sj] += tri_area
    size = np.sqrt(np.einsum("...c,...c->...", weighted, weighted))[..., None]
    normals = np.divide(weighted, size, out=np.zeros_like(weighted), where=size > 0)
    return normals.reshape(N_PARTICLES, 3), area.reshape(N_PARTICLES) / 3.0


def _wind(x, v, t, mass, effect):
    """Provot's fluid force: the normal component of the relative wind, F = C A (n.(u-v)) n."""
    normals, areas = _vertex_normals_and_areas(x)
    relative = np.asarray(effect["velocity"], dtype=float) - v
    along = np.einsum("pc,pc->p", normals, relative)
    return (effect["C"] * areas * along)[:, None] * normals


def _constant_force(x, v, t, mass, effect):
    """Steady uniform acceleration a e: force m a e on every particle."""
    return mass[:, None] * (effect["a"] * np.asarray(effect["direction"], dtype=float))


def _gust(x, v, t, mass, effect):
    """Uniform acceleration oscillating in time, A sin(2 pi f t + phi) e: force m a(t)."""
    amplitude = effect["A"] * math.sin(2.0 * math.pi * effect["f"] * t + effect["phase"])
    return mass[:, None] * (amplitude * np.asarray(effect["direction"], dtype=float))


def _swirl(x, v, t, mass, effect):
    """Horizontal rotating field about a vertical line, F = m s (-(y - yc), x - xc, 0)."""
    xc, yc = effect["center"]
    force = np.zeros_like(x)
    force[:, 0] = -(x[:, 1] - yc)
    force[:, 1] = x[:, 0] - xc
    return (mass * effect["s"])[:, None] * force


# effects that add a force field F(x, v, t) (the others change mass or springs)
_FIELDS = {"air_damping": _air_damping, "quadratic_drag": _quadratic_drag, "wind": _wind,
           "constant_force": _constant_force, "gust": _gust, "swirl": _swirl}
_SPRING_KINDS = {"stiffness_direction", "cubic_springs", "spring_damping"}
_MASS_KINDS = {"mass_step", "mass_gradient"}


def _spring_forces(x, v, model, shared):
    """Spring (and dashpot) forces on every particle, (P, 3).

    Springs: ``f_a = k (L - l) d / L`` (times ``1 + b ((L - l)/l)^2`` if stiffening),
    dashpots: ``f_a = c_s ((v_b - v_a).u) u`` with ``u = d / L``; ``f_b = -f_a``.
    ``shared`` caches the spring geometry of the state.
    """
    if "geometry" not in shared:
        d = x[SPRING_B] - x[SPRING_A]
        shared["geometry"] = d, np.sqrt(np.einsum("sc,sc->s", d, d))
    d, length = shared["geometry"]
    stretch = length - SPRING_REST
    tension = model["k"] * stretch
    if model["cubic_b"]:
        tension = tension * (1.0 + model["cubic_b"] * (stretch / SPRING_REST) ** 2)
    coef = tension / length
    if model["dashpot"]:
        closing = np.einsum("sc,sc->s", v[SPRING_B] - v[SPRING_A], d)
        coef = coef + model["dashpot"] * closing / length**2
    f = coef[:, None] * d
    return _scatter(SPRING_A, f) - _scatter(SPRING_B, f)


def _acceleration(x, v, t, model, shared=None):
    """Acceleration F(x, v, t) / m of every particle (zero on the pinned ones).

    Parameters
    ----------
    x, v : (P, 3) ndarray
        State at time ``t`` (s).
    model : dict from :func:`_model`
    shared : dict, optional
        Per-state cache shared by the models evaluated at this same state (spring geometry,
        spring forces by ``model["springs"]``, field forces by effect and ``model["masses"]``).

    Returns
    -------
    (P, 3) ndarray
    """
    shared = {} if shared is None else shared
    mass = model["mass"]
    force = mass[:, None] * GRAVITY
    key = ("springs", model["springs"])
    if key not in shared:
        shared[key] = _spring_forces(x, v, model, shared)
    force += shared[key]
    for e in model["fields"]:
        key = ("field", e, model["masses"])
        if key not in shared:
            effect = model["effects"][e]
            shared[key] = _FIELDS[effect["kind"]](x, v, t, mass, effect)
        force += shared[key]
    accel = force / mass[:, None]
    accel[~FREE] = 0.0
    return accel


def _constrain(x, tau):
    """One Jacobi pass of Provot's deformation constraint on positions ``x`` (P, 3).

    Every spring longer than ``(1 + tau) l`` proposes moving its ends so that its length
    becomes exactly ``(1 + tau) l`` along its direction: half the excess to each end if both are
    free, all of it to the free end if the other is pinned, nothing if both are pinned. Each
    particle moves by the mean of its proposals. Returns the new positions and the (P,) bool
    mask of the particles that received a proposal.
    """
    d = x[SPRING_B] - x[SPRING_A]
    length = np.sqrt(np.einsum("sc,sc->s", d, d))
    limit = (1.0 + tau) * SPRING_REST
    over = length > limit
    a, b, d, length, limit = SPRING_A[over], SPRING_B[over], d[over], length[over], limit[over]
    free_a, free_b = FREE[a], FREE[b]
    # fraction of d by which each end moves towards the other
    excess = (length - limit) / length
    share_a = np.where(free_a, np.where(free_b, 0.5, 1.0), 0.0) * excess
    share_b = np.where(free_b, np.where(free_a, 0.5, 1.0), 0.0) * excess
    moves = _scatter(a, share_a[:, None] * d) - _scatter(b, share_b[:, None] * d)
    count = (np.bincount(a[free_a], minlength=N_PARTICLES)
             + np.bincount(b[free_b], minlength=N_PARTICLES))
    moved = count > 0
    out = x.copy()
    out[moved] += moves[moved] / count[moved, None]
    return out, moved


def _check_spec(spec):
    effects = spec.get("effects", [])
    kinds = [e.get("kind") for e in effects]
    if len(effects) > 2 or len(set(kinds)) != len(kinds) or any(k not in KINDS for k in kinds):
        raise ValueError(f"spec effects {kinds}: expected at most 2 distinct kinds among "
                         f"{sorted(KINDS)}")
    if int(spec["n_frames"]) < 2:
        raise ValueError(f"spec n_frames={spec['n_frames']}: expected at least 2")


def simulate(spec):
    """Run ``spec`` without noise from the flat sheet at rest.

    Each step is the contract's: ``v' = v + dt F(x, v)/m`` (zero on pinned), ``x' = x + dt v'``,
    one Jacobi pass of the constraint on ``x'``, ``v'' = (x'' - x)/dt`` (zero on pinned); ``F``
    and ``m`` are the true ones, hidden effects included.

    Parameters
    ----------
    spec : dict
        See the module docstring.

    Returns
    -------
    dict with
        ``positions`` : (T, 17, 17, 3) ndarray
        ``constrained`` : (T-1, P) bool ndarray, particles the constraint moved at each step
        ``effect_accel`` : (T-1, P, 3) ndarray, acceleration of the true model minus that of
        the nominal (effect-free, mass 0.001) model at the same state, before the constraint
        ``effect_accel_each`` : (n_effects, T-1, P, 3) ndarray, the same with one effect at a
        time
    """
    _check_spec(spec)
    effects = list(spec["effects"])
    n_steps = int(spec["n_frames"]) - 1
    tau = float(spec["tau"])
    true_model = _model(spec, range(len(effects)))
    nominal_model = _model(spec, [])
    single_models = [_model(spec, [e]) for e in range(len(effects))] if len(effects) > 1 else []

    i, j = np.meshgrid(np.arange(N), np.arange(N), indexing="ij")
    x = np.stack([j * H, i * H, np.zeros((N, N))], axis=-1).reshape(N_PARTICLES, 3)
    v = np.zeros_like(x)
    positions = np.empty((n_steps + 1, N_PARTICLES, 3))
    constrained = np.zeros((n_steps, N_PARTICLES), dtype=bool)
    effect_accel = np.zeros((n_steps, N_PARTICLES, 3))
    effect_each = np.zeros((len(effects), n_steps, N_PARTICLES, 3))
    positions[0] = x
    for step in range(n_steps):
        t = step * DT
        shared = {}        # pieces common to the models evaluated at this state
        accel = _acceleration(x, v, t, true_model, shared)
        if effects:
            nominal = _acceleration(x, v, t, nominal_model, shared)
            effect_accel[step] = accel - nominal
            for e, model in enumerate(single_models):
                effect_each[e, step] = _acceleration(x, v, t, model, shared) - nominal
        v_new = v + DT * accel
        v_new[~FREE] = 0.0
        x_new, constrained[step] = _constrain(x + DT * v_new, tau)
        v = (x_new - x) / DT
        v[~FREE] = 0.0
        x = x_new
        positions[step + 1] = x
    if len(effects) == 1:
        effect_each[0] = effect_accel
    return {"positions": positions.reshape(n_steps + 1, N, N, 3), "constrained": constrained,
            "effect_accel": effect_accel, "effect_accel_each": effect_each}


def _size_and_snr(accel, mask, noise_h):
    """RMS of ``dt^2 |accel|`` in units of h over ``mask``, and its signal-to-noise ratio.

    The one-step prediction residual of a noisy trajectory carries the noise of three frames,
    ``x_{t+1} - 2 x_t + x_{t-1}``, of variance ``6 sigma^2`` per component; the SNR is the
    effect's total displacement over that sd.
    """
    step = DT**2 * accel[mask]                      # (M, 3) displacement per step (m)
    total = float(np.sqrt(np.sum(step**2)))
    rms_h = float(np.sqrt(np.mean(np.sum(step**2, axis=1)))) / H if step.size else 0.0
    if total == 0.0:
        snr = 0.0
    elif noise_h == 0.0:
        snr = math.inf
    else:
        snr = total / (math.sqrt(6.0) * noise_h * H)
    return rms_h, snr


def _share(flags):
    """Mean of a boolean array, 0 when it is empty."""
    return float(np.mean(flags)) if flags.size else 0.0


def make(spec):
    """Trajectory file arrays for ``spec`` (noise added) and the ground truth.

    Gaussian noise of sd ``noise_h * h`` is added to every coordinate of every free particle in
    every frame (``rng = np.random.default_rng(spec["seed"])``); pinned particles are exact.

    Returns
    -------
    dict with the file's keys ``positions`` (T, 17, 17, 3), ``dt``, ``mass`` (scalar nominal
    0.001: mass effects stay hidden), ``gravity`` (3,), ``pinned`` (2, 2) int, ``damping`` (0.0),
    ``meta`` ("{}": no truth), and ``truth``: ``expected_names`` (sorted library names of the
    effects present), ``expected_unexplained`` (bool), ``effect_rms_h`` and ``snr`` over the free
    particle-frames the constraint did not move, ``per_effect`` (list of dicts ``kind``,
    ``expected``, ``effect_rms_h``, ``snr``), ``constraint_share`` (the share of free
    particle-steps the constraint moved) and ``spec``.
    """
    run = simulate(spec)
    positions = run["positions"]
    noise_h = float(spec["noise_h"])
    if noise_h > 0.0:
        rng = np.random.default_rng(spec["seed"])
        noise = rng.standard_normal(positions.shape) * (noise_h * H)
        noise.reshape(positions.shape[0], N_PARTICLES, 3)[:, ~FREE] = 0.0
        positions = positions + noise
    mask = FREE[None, :] & ~run["constrained"]       # (T-1, P) unconstrained free
    rms_h, snr = _size_and_snr(run["effect_accel"], mask, noise_h)
    per_effect = []
    for effect, accel in zip(spec["effects"], run["effect_accel_each"]):
        e_rms, e_snr = _size_and_snr(accel, mask, noise_h)
        per_effect.append({"kind": effect["kind"], "expected": KINDS[effect["kind"]]["expected"],
                           "effect_rms_h": e_rms, "snr": e_snr})
    expected = sorted({KINDS[e["kind"]]["expected"] for e in spec["effects"]} - {"unexplained"})
    truth = {"expected_names": expected,
             "expected_unexplained": any(KINDS[e["kind"]]["expected"] == "unexplained"
                                         for e in spec["effects"]),
             "effect_rms_h": rms_h, "snr": snr, "per_effect": per_effect,
             "constraint_share": _share(run["constrained"][:, FREE]),
             "spec": json.loads(json.dumps(spec))}
    return {"positions": positions, "dt": DT, "mass": MASS, "gravity": GRAVITY.copy(),
            "pinned": np.array(PINNED, dtype=np.int64), "damping": 0.0, "meta": "{}",
            "truth": truth}


FILE_KEYS = ("positions", "dt", "mass", "gravity", "pinned", "damping", "meta")


def write_npz(path, arrays):
    """Write the trajectory file keys of ``arrays`` (a :func:`make` result) to ``path``.

    Only :data:`FILE_KEYS` are written (never ``truth``), each as a numpy array.
    """
    np.savez(path, **{key: np.asarray(arrays[key]) for key in FILE_KEYS})
