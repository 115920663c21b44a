"""Radial snakes (paper 2.3.3, Fig. 6): a disc's region grown into the shape of its motion.

A region is a radius as a function of angle around the disc's centre ``(x, y)``:
``rho_k`` for ``K`` sectors of equal angle. Its energy is

    E = - sum_{pixels inside} s(p) + kappa * sum_k (rho_{k+1} - rho_k)^2

where ``s(p)`` is +1 for a pixel that follows the disc's rotation, -1 for one that
contradicts it, 0 where it cannot tell (see :func:`support`), and ``kappa`` is the
stiffness that keeps the contour from going erratic. The paper's "simple algorithm
inflates the contour and retains it when it gives a better energy value": each iteration
first inflates the whole contour by each of ``steps`` pixels in turn, keeping each
inflation that lowers ``E``, then tries to push every sector outwards by each of ``steps``
pixels and keeps the push that lowers ``E`` most, if any; it stops when nothing is kept or
after ``iterations``.
"""

from __future__ import annotations

import numba
import numpy as np

from replication.cache import KeptArrays


def support(data, xi, eta, omega, *, tolerance=0.3, ambiguous=0.15, empty_cost=0.2,
            ambiguous_cost=0.0):
    """Per-pixel evidence ``s(p)`` for the rotation ``(xi, eta, omega)``, shape ``(H, W)``.

    Normal-flow residuals (pixels/frame) of each pixel with a sufficient gradient, summed
    over frame pairs: ``e_rot = |omega (-Ix (y - eta) + Iy (x - xi)) + It| / |grad I|`` for
    the rotation, ``e_0 = |It| / |grad I|`` for no motion.

    - +1 where ``e_rot < tolerance`` and ``e_rot < e_0 / 2`` (follows the rotation);
    - ``-ambiguous_cost`` where ``e_rot < tolerance`` and ``e_0 < ambiguous`` (too slow to
      tell, e.g. near the rotation centre);
    - ``-empty_cost`` where the gradient is too weak to tell anything (so regions do not
      spread over flat areas, the role of the paper's over-normalisation in 2.3.2);
    - -1 elsewhere (contradicts the rotation).

    Parameters
    ----------
    data : replication.motion.segment.disc_ea.DiscData
    xi, eta, omega : float
    tolerance, ambiguous : float
        Pixels/frame.
    """
    n_pairs, height, width = data.gx.shape
    rows, cols = _coordinates(height, width)
    score = np.zeros((height, width))
    for p in range(n_pairs):
        g = np.where(data.used[p], data.gnorm[p], 1.0)
        motion = omega * (-data.gx[p] * (rows - eta) + data.gy[p] * (cols - xi))
        e_rot = np.abs(motion + data.gt[p]) / g
        e_0 = np.abs(data.gt[p]) / g
        follows = (e_rot < tolerance) & (e_rot < 0.5 * e_0)
        unclear = (e_rot < tolerance) & (e_0 < ambiguous) & ~follows
        evidence = np.where(follows, 1.0, np.where(unclear, -ambiguous_cost, -1.0))
        score += np.where(data.used[p], evidence, -empty_cost)
    return score / n_pairs


def _coordinates(height, width):
    """Row ``(H, 1)`` and column ``(1, W)`` of the pixels, floats: broadcast against
    ``(H, W)`` maps they give each pixel the values of ``np.mgrid``, without its two
    full arrays."""
    return (np.arange(height, dtype=float)[:, None], np.arange(width, dtype=float)[None, :])


POLAR_CACHE_BYTES = 64 << 20   # the maps of 64 centres on 256 x 256 frames
_POLAR = KeptArrays(max_bytes=POLAR_CACHE_BYTES)


def polar(shape, x, y, n_sectors):
    """Distance to ``(x, y)`` and sector index of every pixel, ``(H, W)`` each (read-only).

    The last centres' maps are kept (up to :data:`POLAR_CACHE_BYTES`): :func:`sector_profiles`
    and :func:`region_mask` of one snake need the same, and the pipeline's second round
    (``snake.rounds = 2``) snakes again from each disc's centre; these arctan2 and hypot
    maps were about half of a snake's time.
    """
    key = (tuple(int(v) for v in shape), float(x), float(y), int(n_sectors))

    def maps():
        (height, width), x, y, n_sectors = key
        rows, cols = _coordinates(height, width)
        # full (H, W) operands, as np.mgrid gave: numpy may take another (SIMD) loop for
        # hypot and arctan2 on broadcast ones, with other last bits
        dx, dy = np.repeat(cols - x, height, axis=0), np.repeat(rows - y, width, axis=1)
        sector = (np.floor((np.arctan2(dy, dx) + np.pi) / (2 * np.pi) * n_sectors)
                  .astype(np.int64) % n_sectors)
        return np.hypot(dx, dy), sector

    return _POLAR.get(key, maps)


def sector_profiles(score, x, y, *, n_sectors=64, rho_max=120):
    """Cumulative energy of each sector as a function of its radius.

    Parameters
    ----------
    score : (H, W) ndarray
        ``s(p)`` of :func:`support`.
    x, y : float
        The region's centre (the disc's centre).
    n_sectors : int
    rho_max : int
        Largest radius considered, pixels.

    Returns
    -------
    cumulative : (n_sectors, rho_max + 1) ndarray
        ``cumulative[k, j] = - sum s(p)`` over the pixels of sector ``k`` with ``rho < j``.
    """
    rho, sector = polar(score.shape, x, y, n_sectors)
    near = rho < rho_max
    ring = np.floor(rho[near]).astype(np.int64) + 1
    # bincount adds the weights in pixel order, as np.add.at did (the same sums), faster
    energy = np.bincount(sector[near] * (rho_max + 1) + ring, weights=-score[near],
                         minlength=n_sectors * (rho_max + 1))
    return np.cumsum(energy.reshape(n_sectors, rho_max + 1), axis=1)


def stiffness_energy(rho, kappa):
    """``kappa * sum_k (rho_{k+1} - rho_k)^2`` of a closed radial contour ``rho`` (K,).

    Parameters
    ----------
    rho : (K,) ndarray
    kappa : float
    """
    return kappa * float(np.sum((np.roll(rho, -1) - rho) ** 2))


@numba.njit(cache=True)
def _inflate(cumulative, rho, kappa, moves, iterations):
    """The loop of :func:`inflate` (see there); returns the energy after each iteration."""
    n_sectors, size = cumulative.shape
    history = np.empty(iterations + 1)
    energy = kappa * np.sum((np.roll(rho, -1) - rho) ** 2)
    for k in range(n_sectors):
        energy += cumulative[k, rho[k]]
    history[0] = energy
    done = 0
    for it in range(iterations):
        changed = False
        for step in moves:          # the whole contour inflated, while that lowers E
            if step <= 0:
                continue
            delta = 0.0
            for k in range(n_sectors):
                new = min(rho[k] + step, size - 1)
                right = min(rho[(k + 1) % n_sectors] + step, size - 1)
                delta += cumulative[k, new] - cumulative[k, rho[k]]
                delta += kappa * ((right - new) ** 2 - (rho[(k + 1) % n_sectors] - rho[k]) ** 2)
            if delta < 0.0:
                for k in range(n_sectors):
                    rho[k] = min(rho[k] + step, size - 1)
                energy += delta
                changed = True
        for k in range(n_sectors):
            left, right = rho[k - 1], rho[(k + 1) % n_sectors]
            best_delta, best = 0.0, rho[k]
            for step in moves:
                new = rho[k] + step
                if new >= size or new < 1:
                    continue
                delta = (cumulative[k, new] - cumulative[k, rho[k]]
                         + kappa * ((new - left) ** 2 + (right - new) ** 2
                                    - (rho[k] - left) ** 2 - (right - rho[k]) ** 2))
                if delta < best_delta:
                    best_delta, best = delta, new
            if best != rho[k]:
                rho[k] = best
                energy += best_delta
                changed = True
        done = it + 1
        history[done] = energy
        if not changed:
            break
    return history[: done + 1]


def inflate(cumulative, rho0, *, kappa=0.05, steps=(8, 4, 2, 1), iterations=20,
            deflate=False):
    """The paper's snake: inflate sectors while the energy decreases.

    Parameters
    ----------
    cumulative : (K, J) ndarray
        From :func:`sector_profiles`.
    rho0 : float
        Starting radius of every sector (the disc's radius), pixels.
    kappa : float
        Stiffness.
    steps : sequence of int
        Pushes tried for each sector, pixels.
    iterations : int
        The paper: stable after 5 to 20.
    deflate : bool
        Also try pulling sectors inwards by the same steps (not in the paper, which only
        inflates); lets a region drop the part of its starting disc that lies outside.

    Returns
    -------
    rho : (K,) ndarray of int
    history : list of float
        The energy after each iteration (first entry: the starting disc); non-increasing.
    """
    n_sectors, size = cumulative.shape
    moves = [int(v) for v in steps] + ([-int(v) for v in steps] if deflate else [])
    rho = np.full(n_sectors, min(int(round(rho0)), size - 1), dtype=np.int64)
    history = _inflate(np.ascontiguousarray(cumulative, dtype=np.float64), rho, float(kappa),
                       np.array(moves, dtype=np.int64), int(iterations))
    return rho, [float(v) for v in history]


def region_mask(shape, x, y, rho):
    """Pixels inside the radial contour ``rho`` (K,) centred on ``(x, y)``, ``(H, W)`` bool.

    Parameters
    ----------
    shape : (H, W)
    x, y : float
    rho : (K,) ndarray
    """
    distance, sector = polar(shape, x, y, rho.size)
    return distance < rho[sector]


def radial_snake(data, disc, *, tolerance=0.3, ambiguous=0.15, empty_cost=0.2,
                 ambiguous_cost=0.0, n_sectors=64, rho_max=120, kappa=0.05,
                 steps=(8, 4, 2, 1), iterations=20, deflate=False):
    """One disc ``(x, y, r, xi, eta, omega)`` refined into a region (paper 2.3.3).

    Parameters
    ----------
    data : replication.motion.segment.disc_ea.DiscData
    disc : (6,) array_like
    tolerance, ambiguous, empty_cost, ambiguous_cost : float
        The evidence of :func:`support`.
    n_sectors, rho_max : int
        As :func:`sector_profiles`.
    kappa, steps, iterations, deflate
        As :func:`inflate`.

    Returns
    -------
    dict
        ``mask`` ((H, W) bool), ``rho`` ((K,) radii), ``centre`` ((x, y)), ``energy``
        (history), ``iterations``.
    """
    x, y, r, xi, eta, omega = (float(v) for v in disc)
    score = support(data, xi, eta, omega, tolerance=tolerance, ambiguous=ambiguous,
                    empty_cost=empty_cost, ambiguous_cost=ambiguous_cost)
    cumulative = sector_profiles(score, x, y, n_sectors=n_sectors, rho_max=rho_max)
    rho, history = inflate(cumulative, r, kappa=kappa, steps=steps, iterations=iterations,
                           deflate=deflate)
    return {"mask": region_mask(score.shape, x, y, rho), "rho": rho, "centre": (x, y),
            "energy": history, "iterations": len(history) - 1}
