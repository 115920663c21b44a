"""Spring sums, forces, dashpots, normals and scatter matrices (replication.cloth.geometry),
against the physical definitions of docs/cloth-model.md written out spring by spring."""

import numpy as np
import pytest

from replication.cloth import geometry

# Round-off tolerance: the quantities compared are O(0.01..1) and each is a sum of at most
# ~12 terms of that size in double precision (error ~1e-15), so 1e-12 leaves three orders
# of margin, while any modelling error (a wrong sign, a swapped type, a missing spring)
# changes them by at least ~1e-3.
ATOL = 1e-12


def _pairs(n):
    """``(a, b, type)`` of every spring, written from the table of docs/cloth-model.md."""
    p = lambda i, j: i * n + j  # noqa: E731
    out = []
    for i in range(n):
        for j in range(n):
            if j + 1 < n:
                out.append((p(i, j), p(i, j + 1), 0))
            if i + 1 < n:
                out.append((p(i, j), p(i + 1, j), 1))
            if i + 1 < n and j + 1 < n:
                out.append((p(i, j), p(i + 1, j + 1), 2))
                out.append((p(i, j + 1), p(i + 1, j), 3))
            if j + 2 < n:
                out.append((p(i, j), p(i, j + 2), 4))
            if i + 2 < n:
                out.append((p(i, j), p(i + 2, j), 5))
    return out


def _hooke(x, n, rest, k):
    """Spring forces (F, P, 3) from ``f_a = k (L - l) d / L``, ``f_b = -f_a`` (a spring of
    length 0 exerts none)."""
    f = np.zeros_like(x)
    for a, b, t in _pairs(n):
        d = x[:, b] - x[:, a]
        length = np.linalg.norm(d, axis=1, keepdims=True)
        safe = np.where(length > 0, length, 1.0)
        fa = np.where(length > 0, k[t] * (length - rest[t]) * d / safe, 0.0)
        f[:, a] += fa
        f[:, b] -= fa
    return f


def _grid(n, hx, hy):
    """Flat sheet ``x = (j*hx, i*hy, 0)``, (P, 3)."""
    i, j = np.divmod(np.arange(n * n), n)
    return np.stack([j * hx, i * hy, np.zeros(n * n)], axis=1)


def _rotation(rng):
    """A random proper rotation (det +1)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _deformed(rng, n, frames=2, h=0.1, jitter=0.02):
    """Randomly perturbed sheets (F, P, 3): no spring near zero length."""
    return _grid(n, h, h)[None] + rng.normal(scale=jitter, size=(frames, n * n, 3))


def _force(x, n, rest, k):
    ops = geometry.MeshOperators(n)
    return geometry.spring_force(*geometry.spring_sums(ops, x), rest, k)


def test_spring_sums_are_signed_sums_of_d_and_unit_d_per_type():
    """A_t = sum of +-d and B_t = sum of +-d/L over the springs of type t at each end."""
    rng = np.random.default_rng(0)
    n = 5
    x = _deformed(rng, n)
    A, B = geometry.spring_sums(geometry.MeshOperators(n), x)
    assert A.shape == B.shape == (6,) + x.shape
    want_a, want_b = np.zeros_like(A), np.zeros_like(B)
    for a, b, t in _pairs(n):
        d = x[:, b] - x[:, a]
        u = d / np.linalg.norm(d, axis=1, keepdims=True)
        want_a[t, :, a] += d
        want_a[t, :, b] -= d
        want_b[t, :, a] += u
        want_b[t, :, b] -= u
    np.testing.assert_allclose(A, want_a, rtol=0, atol=ATOL)
    np.testing.assert_allclose(B, want_b, rtol=0, atol=ATOL)


def test_spring_force_is_the_hooke_sum_with_per_type_rest_and_stiffness():
    """sum_t k_t (A_t - l_t B_t) equals sum over springs of k (L - l) d / L, per type."""
    rng = np.random.default_rng(1)
    n = 5
    x = _deformed(rng, n, frames=3)
    rest = rng.uniform(0.05, 0.25, size=6)
    k = rng.uniform(1.0, 8.0, size=6)
    got = _force(x, n, rest, k)
    assert got.shape == x.shape
    np.testing.assert_allclose(got, _hooke(x, n, rest, k), rtol=0, atol=ATOL)


def test_spring_force_is_zero_at_rest_shape_and_rotates_with_a_rigid_motion():
    """At rest lengths the force vanishes, also after a rigid motion; for a deformed mesh
    F(R x + t) = R F(x)."""
    rng = np.random.default_rng(2)
    n = 6
    hx, hy = 0.09, 0.12   # anisotropic: a swap of types 0/1 or 4/5 would not be at rest
    rest = np.array([hx, hy, np.hypot(hx, hy), np.hypot(hx, hy), 2 * hx, 2 * hy])
    k = np.array([4.0, 3.0, 2.0, 5.0, 1.5, 6.0])
    R, shift = _rotation(rng), rng.normal(size=3)
    flat = _grid(n, hx, hy)
    at_rest = np.stack([flat, flat @ R.T + shift])
    # residues are k * d * (1 - l/L) with L = l up to round-off: ~1e-16 * k * 2h
    np.testing.assert_allclose(_force(at_rest, n, rest, k), 0.0, rtol=0, atol=ATOL)
    # the same lengths with the wrong rest lengths do give a force: the test can see one
    assert np.abs(_force(at_rest, n, rest[[1, 0, 2, 3, 5, 4]], k)).max() > 1e-2
    x = _deformed(rng, n, frames=1)
    moved = x @ R.T + shift
    np.testing.assert_allclose(_force(moved, n, rest, k), _force(x, n, rest, k) @ R.T,
                               rtol=0, atol=ATOL)


def test_internal_spring_forces_sum_to_zero_force_and_zero_torque():
    """Newton's third law: the total spring force and its total torque vanish (central
    forces), on a random deformed mesh."""
    rng = np.random.default_rng(3)
    n = 7
    x = _deformed(rng, n, frames=2, jitter=0.03)
    f = _force(x, n, rng.uniform(0.05, 0.25, size=6), rng.uniform(1.0, 8.0, size=6))
    assert np.abs(f).max() > 0.05   # the forces are not trivially zero
    # a sum of ~P = 49 terms of size <= 1: round-off ~1e-14
    np.testing.assert_allclose(f.sum(axis=1), 0.0, rtol=0, atol=ATOL)
    np.testing.assert_allclose(np.cross(x, f).sum(axis=1), 0.0, rtol=0, atol=ATOL)


def test_a_stretched_spring_pulls_its_ends_together_and_a_compressed_one_pushes():
    """One type-0 spring stretched (then compressed) by delta: its ends feel +-k delta
    along the spring, towards each other (away from each other)."""
    n, h, k0, delta = 3, 0.1, 4.0, 0.01
    rest = np.array([h, h, h * np.sqrt(2), h * np.sqrt(2), 2 * h, 2 * h])
    k = np.array([k0, 0, 0, 0, 0, 0])   # only structural springs along j
    for sign in (1.0, -1.0):
        x = _grid(n, h, h)
        x[2 * n + 2, 0] += sign * delta   # particle (2, 2): spring (2,1)-(2,2) changes
        f = _force(x[None], n, rest, k)[0]
        want = np.zeros_like(x)
        want[2 * n + 1, 0] = sign * k0 * delta   # end a: towards b when stretched
        want[2 * n + 2, 0] = -sign * k0 * delta  # end b: towards a when stretched
        np.testing.assert_allclose(f, want, rtol=0, atol=ATOL)


def test_a_spring_of_length_zero_exerts_no_force():
    """Two coincident particles: their spring has no direction and no force; all others
    act as usual and nothing is NaN."""
    rng = np.random.default_rng(4)
    n = 3
    x = _deformed(rng, n, frames=1)
    x[0, 1] = x[0, 0]   # spring (0,0)-(0,1) of length 0
    rest = np.full(6, 0.1)
    k = np.arange(1.0, 7.0)
    got = _force(x, n, rest, k)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got, _hooke(x, n, rest, k), rtol=0, atol=ATOL)


def test_dashpot_sums_are_relative_velocity_along_each_spring():
    """sum of +-((v_b - v_a).u) u per spring; zero for a rigid-body velocity field."""
    rng = np.random.default_rng(5)
    n = 5
    ops = geometry.MeshOperators(n)
    x = _deformed(rng, n)
    v = rng.normal(size=x.shape)
    want = np.zeros_like(x)
    for a, b, _ in _pairs(n):
        d = x[:, b] - x[:, a]
        u = d / np.linalg.norm(d, axis=1, keepdims=True)
        rel = np.sum((v[:, b] - v[:, a]) * u, axis=1, keepdims=True) * u
        want[:, a] += rel
        want[:, b] -= rel
    np.testing.assert_allclose(geometry.dashpot_sums(ops, x, v), want, rtol=0, atol=ATOL)
    omega, drift = rng.normal(size=3), rng.normal(size=3)
    rigid = np.cross(omega, x) + drift   # no spring changes length
    np.testing.assert_allclose(geometry.dashpot_sums(ops, x, rigid), 0.0, rtol=0, atol=ATOL)


def test_normals_of_a_flat_sheet_point_up_and_rotate_with_it():
    """x = (j h, i h, 0): normal +z everywhere (cross of j-direction and i-direction)."""
    rng = np.random.default_rng(6)
    n = 5
    flat = _grid(n, 0.1, 0.1)[None]
    np.testing.assert_allclose(geometry.normals(flat, n),
                               np.broadcast_to([0.0, 0.0, 1.0], flat.shape), atol=ATOL)
    R = _rotation(rng)
    np.testing.assert_allclose(geometry.normals(flat @ R.T + 1.0, n),
                               np.broadcast_to(R[:, 2], flat.shape), atol=ATOL)


def test_normals_match_the_analytic_normal_of_a_quadratic_surface_inside():
    """z = a x^2 + b y^2: central differences are exact for a quadratic, so interior
    normals are (-2ax, -2by, 1) / norm; every normal has unit length."""
    n, h, a, b = 9, 0.1, 0.7, -1.3
    x = _grid(n, h, h)
    x[:, 2] = a * x[:, 0] ** 2 + b * x[:, 1] ** 2
    got = geometry.normals(x[None], n)[0]
    want = np.stack([-2 * a * x[:, 0], -2 * b * x[:, 1], np.ones(n * n)], axis=1)
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    i, j = np.divmod(np.arange(n * n), n)
    inside = (i > 0) & (i < n - 1) & (j > 0) & (j < n - 1)
    np.testing.assert_allclose(got[inside], want[inside], rtol=0, atol=ATOL)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, rtol=0, atol=ATOL)


def test_area_normals_share_triangle_areas_by_thirds_on_a_flat_sheet():
    """Flat sheet of spacing h: interior particles touch 6 triangles of area h^2/2, so get
    h^2; corners on the split diagonal 2 triangles (h^2/3), the others 1 (h^2/6)."""
    n, h = 5, 0.1
    got = geometry.area_normals(_grid(n, h, h)[None], n)[0].reshape(n, n, 3)
    np.testing.assert_allclose(got[..., :2], 0.0, atol=ATOL)
    z = got[..., 2]
    np.testing.assert_allclose(z[1:-1, 1:-1], h * h, rtol=1e-12)
    np.testing.assert_allclose([z[0, 0], z[-1, -1]], h * h / 3, rtol=1e-12)
    np.testing.assert_allclose([z[0, -1], z[-1, 0]], h * h / 6, rtol=1e-12)
    # edge particles (not corners): 3 triangles -> h^2/2
    np.testing.assert_allclose(np.concatenate([z[0, 1:-1], z[-1, 1:-1], z[1:-1, 0],
                                               z[1:-1, -1]]), h * h / 2, rtol=1e-12)
    np.testing.assert_allclose(z.sum(), ((n - 1) * h) ** 2, rtol=1e-12)


def test_area_normals_sum_to_the_vector_area_of_the_boundary_loop():
    """For any sheet the per-particle shares add up to the vector area
    1/2 sum x_k x x_(k+1) around the boundary (j up, i up, j down, i down), and point
    the same way as :func:`normals`."""
    rng = np.random.default_rng(7)
    n = 6
    x = _deformed(rng, n, frames=1, jitter=0.02)[0]
    grid = x.reshape(n, n, 3)
    loop = np.concatenate([grid[0, :-1], grid[:-1, -1], grid[-1, :0:-1], grid[:0:-1, 0]])
    want = 0.5 * np.cross(loop, np.roll(loop, -1, axis=0)).sum(axis=0)
    got = geometry.area_normals(x[None], n)[0]
    np.testing.assert_allclose(got.sum(axis=0), want, rtol=0, atol=ATOL)
    assert np.all(np.sum(got * geometry.normals(x[None], n)[0], axis=1) > 0)


def test_scatter_matrix_has_plus_one_at_end_a_and_minus_one_at_end_b():
    """One column per spring with exactly +1 at a and -1 at b; the set of columns is the
    spring table of the docs."""
    n = 4
    m = geometry.scatter_matrix(n).toarray()
    assert m.shape == (n * n, len(_pairs(n)))
    assert np.all(np.sum(m != 0, axis=0) == 2)
    ends = sorted((int(np.flatnonzero(col == 1)[0]), int(np.flatnonzero(col == -1)[0]))
                  for col in m.T)
    assert ends == sorted((a, b) for a, b, _ in _pairs(n))


def test_scatter_adds_each_spring_vector_to_a_and_subtracts_it_from_b():
    """scatter(matrix, per_spring) equals the explicit accumulation, frame by frame."""
    rng = np.random.default_rng(8)
    n = 4
    m = geometry.scatter_matrix(n)
    cols = m.toarray().T
    a = np.array([np.flatnonzero(c == 1)[0] for c in cols])
    b = np.array([np.flatnonzero(c == -1)[0] for c in cols])
    per_spring = rng.normal(size=(3, len(cols), 3))
    want = np.zeros((3, n * n, 3))
    for s in range(len(cols)):
        want[:, a[s]] += per_spring[:, s]
        want[:, b[s]] -= per_spring[:, s]
    got = geometry.scatter(m, per_spring)
    assert got.shape == (3, n * n, 3)
    np.testing.assert_allclose(got, want, rtol=0, atol=ATOL)


def test_type_lengths_of_the_flat_sheet_and_of_a_stretched_frame():
    """The one measure of spring lengths per type: on the contract's flat sheet the six
    types are h, h, h sqrt 2, h sqrt 2, 2h, 2h; with a second frame stretched by 1.5 along
    x the mean of a type is the average of both frames, the median the middle value."""
    from replication.cloth.mesh import flat_rest_positions, spacing, type_lengths

    n = 5
    h = spacing(n)
    flat = flat_rest_positions(n)
    expected = h * np.array([1.0, 1.0, np.sqrt(2), np.sqrt(2), 2.0, 2.0])
    np.testing.assert_allclose(type_lengths(flat, n), expected, rtol=1e-14)
    stretched = flat * np.array([1.5, 1.0, 1.0])
    both = np.stack([flat, flat, stretched])
    mean = type_lengths(both, n)
    # type 0 joins (i, j)-(i, j+1): along x, so 1.5 h in the stretched frame
    assert mean[0] == pytest.approx((2 * h + 1.5 * h) / 3, rel=1e-14)
    assert mean[1] == pytest.approx(h, rel=1e-14)            # along y: unchanged
    assert type_lengths(both, n, statistic="median")[0] == pytest.approx(h, rel=1e-14)
    with pytest.raises(ValueError, match="statistic='max'"):
        type_lengths(flat, n, statistic="max")


def test_stretched_ends_marks_both_ends_of_each_spring_strictly_over_its_limit():
    from replication.cloth import kernels

    rng = np.random.default_rng(5)
    ops = geometry.MeshOperators(5)
    a, b = ops.a, ops.b
    positions = rng.normal(0, 1, (4, 25, 3))
    length = np.sqrt(((positions[:, b] - positions[:, a]) ** 2).sum(axis=2))
    limit = np.median(length, axis=0)
    limit[::3] = length[2, ::3]                     # exactly at the limit: not stretched
    expected = np.zeros((4, 25), dtype=bool)
    for f in range(4):
        for s in range(len(a)):
            if length[f, s] > limit[s]:
                expected[f, a[s]] = expected[f, b[s]] = True
    assert np.array_equal(kernels.stretched_ends(positions, a, b, limit), expected)
