"""Baselines for one rotation: optical flow + rigid fit, direct least squares, pymoo DE.

All take ``frames`` (T, H, W) and return ``{xi, eta, omega}`` (and a few diagnostics).
Optical flow and direct least squares use the first frame pair; DE scores every pair.
"""

from __future__ import annotations

import hashlib
import math
import os
import sys
from pathlib import Path

import numpy as np
from scipy import ndimage

from replication.motion.derivatives import sequence_derivatives
from replication.motion.irc import tukey_weights
from replication.optim.objective import Objective


def _centre_from_affine(a, b, tx, ty):
    """``(xi, eta, omega)`` of the displacement ``d = [[a, -b], [b, a]] (p - c0) + t``.

    The map ``p -> p + d`` is rotated by ``atan2(b, 1 + a)`` (its scale is dropped) and
    its fixed point is the rotation centre, relative to the origin ``c0`` of ``p``.
    """
    omega = math.atan2(b, 1.0 + a)
    linear = np.array([[a, -b], [b, a]])
    try:
        centre = np.linalg.solve(-linear, np.array([tx, ty]))
    except np.linalg.LinAlgError:
        centre = np.array([np.nan, np.nan])
    return float(centre[0]), float(centre[1]), float(omega)


def rigid_fit(u, v, mask, *, tukey_c=1.0, iterations=10):
    """Robust least-squares rotation fitted to a displacement field.

    Fits ``(u, v) = [[a, -b], [b, a]] (x - x0, y - y0) + (tx, ty)`` (exact for a finite
    rotation about any centre, plus a scale) by iteratively reweighted least squares with
    Tukey's biweight on the displacement residual (pixels).

    Parameters
    ----------
    u, v : (H, W) ndarray
        Displacement along x (columns) and y (rows), pixels/frame.
    mask : (H, W) ndarray of bool
        Pixels used.
    tukey_c : float
        Tukey's constant, pixels.

    Returns
    -------
    dict
        ``xi, eta, omega``.
    """
    rows, cols = np.nonzero(mask)
    if rows.size < 3:
        return {"xi": math.nan, "eta": math.nan, "omega": math.nan}
    x0, y0 = cols.mean(), rows.mean()
    X, Y = cols - x0, rows - y0
    one, zero = np.ones_like(X), np.zeros_like(X)
    design = np.concatenate([np.stack([X, -Y, one, zero], axis=1),
                             np.stack([Y, X, zero, one], axis=1)])
    target = np.concatenate([u[rows, cols], v[rows, cols]])
    weights = np.ones(rows.size)
    params = np.zeros(4)
    for _ in range(iterations):
        root = np.sqrt(np.concatenate([weights, weights]))
        params, *_ = np.linalg.lstsq(design * root[:, None], target * root, rcond=None)
        residual = (design @ params - target).reshape(2, -1)
        weights = tukey_weights(np.hypot(*residual), tukey_c)
        if np.count_nonzero(weights) < 3:
            break
    xi, eta, omega = _centre_from_affine(*params)
    return {"xi": float(xi + x0), "eta": float(eta + y0), "omega": omega}


def optical_flow_rotation(frames, *, method="tvl1", motion_min=0.25, erode=5, tukey_c=1.0,
                          flow_options=None, cache_dir=None):
    """scikit-image optical flow on the first pair, then :func:`rigid_fit` on moving pixels.

    Parameters
    ----------
    frames : (T, H, W) ndarray
    method : {"tvl1", "ilk"}
        ``skimage.registration.optical_flow_tvl1`` or ``optical_flow_ilk``.
    motion_min : float
        Pixels whose flow is shorter than this (pixels/frame) are taken as background.
    erode : int
        The moving region is eroded by a disc of this radius (pixels): flow is smoothed
        across the object's edge, as the IRC refinement's region is.
    flow_options : dict or None
        Keyword arguments of the flow function.
    cache_dir : str or Path, optional
        Keep each flow field there (:func:`flow_field`): studies that vary only the
        moving-region settings or the other method's options compute each field once.

    Returns
    -------
    dict
        ``xi, eta, omega`` and ``flow`` ((2, H, W): ``u`` along x, ``v`` along y).
    """
    u, v = flow_field(frames[0], frames[1], method=method, options=flow_options,
                      cache_dir=cache_dir)
    moving = np.hypot(u, v) >= motion_min
    if erode > 0:
        rows, cols = np.mgrid[-erode: erode + 1, -erode: erode + 1]
        moving = ndimage.binary_erosion(moving, rows ** 2 + cols ** 2 <= erode ** 2)
    border = 4
    moving[:border], moving[-border:], moving[:, :border], moving[:, -border:] = (False,) * 4
    fit = rigid_fit(u, v, moving, tukey_c=tukey_c)
    fit["flow"] = np.stack([u, v])
    return fit


# intensity spans the flow baselines take as they are; others are mapped to 0..1
UNIT_SPAN = (2.0 ** -8, 4.0)
UNIT_LIMIT = 1e4      # ... and values of at most this magnitude (float32 holds them)
_NOTED = set()


def unit_intensities(first, second):
    """The frame pair on the intensity scale scikit-image's flow parameters assume.

    TV-L1's data and smoothness weights and iLK's gradients are tuned for intensities of
    order 1 (8- and 16-bit frames are read as 0..1), and scikit-image computes in float32:
    frames read as stored (float or signed integer files: 0..255, 12-bit counts, 1e-90) give
    other answers, NaN or an overflow. A pair whose values span less than ``UNIT_SPAN[0]``
    or more than ``UNIT_SPAN[1]``, or reach beyond ``UNIT_LIMIT`` in magnitude, is mapped
    linearly (one map for both frames) to 0..1; any other pair is returned unchanged.

    Parameters
    ----------
    first, second : (H, W) ndarray
        Finite frames (the readers refuse NaN and inf).

    Returns
    -------
    first, second : (H, W) ndarray
    mapped : tuple of float or None
        The ``(low, high)`` values mapped to 0 and 1, or None when unchanged.
    """
    first, second = np.asarray(first, dtype=float), np.asarray(second, dtype=float)
    # divide by the largest magnitude first: high - low may overflow near 1e308
    scale = max(float(np.abs(first).max()), float(np.abs(second).max()))
    low = min(float(first.min()), float(second.min()))
    high = max(float(first.max()), float(second.max()))
    unit = high / scale - low / scale if scale > 0 else 0.0   # the span over scale
    span = unit * scale                                          # inf beyond 1.8e308
    if not unit > 0 or (UNIT_SPAN[0] <= span <= UNIT_SPAN[1] and scale <= UNIT_LIMIT):
        return first, second, None
    return ((first / scale - low / scale) / unit, (second / scale - low / scale) / unit,
            (low, high))


def flow_field(first, second, *, method="tvl1", options=None, cache_dir=None):
    """scikit-image's optical flow from ``first`` to ``second``, as ``(u, v)`` (along x, y).

    The pair is first put on the intensity scale the flow expects
    (:func:`unit_intensities`; a ``note:`` on stderr, once per range, says when it was
    mapped). With ``cache_dir``, the field is read from there when it was computed before
    for the same two images, method, options and scikit-image version (a file named by
    their SHA-256), and written there otherwise: the same numbers, computed once.

    Parameters
    ----------
    first, second : (H, W) ndarray
    method : {"tvl1", "ilk"}
    options : dict or None
        Keyword arguments of the flow function.
    cache_dir : str or Path, optional
    """
    import skimage
    from skimage.registration import optical_flow_ilk, optical_flow_tvl1

    function = {"tvl1": optical_flow_tvl1, "ilk": optical_flow_ilk}[method]
    first, second, mapped = unit_intensities(first, second)
    if mapped is not None and mapped not in _NOTED:
        _NOTED.add(mapped)
        print(f"note: frame intensities span {mapped[0]:.3g}..{mapped[1]:.3g}; the optical-"
              "flow baselines (scikit-image, tuned for 0..1) see them mapped to 0..1 "
              "(docs/data-formats.md, intensities)", file=sys.stderr, flush=True)
    path = None
    if cache_dir is not None:
        first, second = np.ascontiguousarray(first), np.ascontiguousarray(second)
        key = (method, sorted((options or {}).items()), skimage.__version__, first.shape,
               first.dtype.str, second.shape, second.dtype.str)
        digest = hashlib.sha256(repr(key if mapped is None else (*key, mapped)).encode())
        digest.update(first.tobytes())
        digest.update(second.tobytes())
        path = Path(cache_dir) / f"{digest.hexdigest()}.npy"
        if path.is_file():
            u, v = np.load(path)
            return u, v
    # skimage returns (row, col) = (v, u), the displacement from frame 0 to frame 1
    v, u = function(first, second, **(options or {}))
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f"{path.stem}.{os.getpid()}.partial.npy")
        np.save(partial, np.stack([u, v]))
        os.replace(partial, path)   # whole files only: workers may share the folder
    return u, v


def direct_least_squares(frames, *, sigma=1.5, relative_threshold=0.15):
    """Least squares on the IRC equation over every pixel with a sufficient gradient.

    With ``p = omega eta`` and ``q = -omega xi`` the IRC equation is linear:
    ``omega (Iy x - Ix y) + p Ix + q Iy = -It``. No region is selected, so the static
    background takes part, as it would in a naive use of the equation.

    Parameters
    ----------
    frames : (T, H, W) ndarray
    sigma : float
        Pre-smoothing, pixels.
    relative_threshold : float
        Gradient threshold (:func:`gradient_threshold`).

    Returns
    -------
    dict
        ``xi, eta, omega``.
    """
    pixels = sequence_derivatives(frames[:2], sigma=sigma, relative_threshold=relative_threshold)
    x0, y0 = pixels.x.mean(), pixels.y.mean()
    X, Y = pixels.x - x0, pixels.y - y0
    design = np.stack([pixels.gy * X - pixels.gx * Y, pixels.gx, pixels.gy], axis=1)
    (omega, p, q), *_ = np.linalg.lstsq(design, -pixels.gt, rcond=None)
    if omega == 0:
        return {"xi": math.nan, "eta": math.nan, "omega": 0.0}
    return {"xi": float(x0 - q / omega), "eta": float(y0 + p / omega), "omega": float(omega)}


def irc_cost(pixels, *, tau=2.0):
    """The objective ``evaluate(X: (pop, 3)) -> (pop,)`` of the IRC residual.

    For ``X[k] = (xi, eta, omega)``: the mean over pixels of ``min(d^2, tau^2)``, where
    ``d`` is the distance (pixels) from ``(xi, eta)`` to the pixel's IRC line (the paper's
    2.3 residual normalised by the gradient, truncated so the background does not
    dominate): a continuous form of the accumulator's peak. ``omega = 0`` scores ``tau^2``.

    Parameters
    ----------
    pixels : PixelDerivatives
    tau : float
        Truncation distance, pixels.
    """
    x, y, gx, gy, gt = pixels.x, pixels.y, pixels.gx, pixels.gy, pixels.gt
    norm = np.hypot(gx, gy)

    def evaluate(X):
        X = np.atleast_2d(X)
        xi, eta, omega = X[:, 0:1], X[:, 1:2], X[:, 2:3]
        safe = np.where(omega == 0, 1.0, omega)
        residual = -gx * (y - eta) + gy * (x - xi) + gt / safe
        cost = np.minimum((residual / norm) ** 2, tau * tau).mean(axis=1)
        return np.where(omega[:, 0] == 0, tau * tau, cost)

    return evaluate


def de_rotation(frames, *, seed, sigma=1.5, relative_threshold=0.15, tau=2.0,
                max_evals=1500, pop_size=30, omega_bounds=(-0.05, 0.05), max_pixels=8000):
    """pymoo differential evolution on :func:`irc_cost` over ``(xi, eta, omega)``.

    The search box is the image for ``(xi, eta)`` and the paper's sweep interval for
    ``omega``. It scores through the suite's one objective contract
    (:class:`~replication.optim.objective.Objective` and
    :func:`~replication.optim.pymoo_adapters.run_pymoo`, like the cloth baselines): exactly
    ``max_evals`` evaluations, counted one vector at a time, and the best vector seen.
    Seeded by ``seed``, so a run is reproducible. (pymoo's CMA-ES wraps the ``cma``
    package, whose runs differed in the last digits and in the evaluation count between
    identical calls, hence DE.)

    Parameters
    ----------
    seed : int
    max_evals : int
        Evaluation budget.
    max_pixels : int
        Pixels scored per evaluation (an evenly strided subset, for speed).

    Returns
    -------
    dict
        ``xi, eta, omega, cost, evaluations``.
    """
    # imported here: pymoo's CMA-ES, which the adapters import, imports matplotlib's pyplot
    # and scipy.stats (about 2 s), which a motion run without this baseline does not need
    from replication.optim.pymoo_adapters import run_pymoo

    pixels = sequence_derivatives(frames, sigma=sigma, relative_threshold=relative_threshold)
    stride = max(1, len(pixels) // max_pixels)
    subset = type(pixels)(*(getattr(pixels, f)[::stride]
                            for f in ("x", "y", "gx", "gy", "gt", "pair")))
    height, width = frames.shape[1:]
    objective = Objective(irc_cost(subset, tau=tau), [0.0, 0.0, omega_bounds[0]],
                          [width - 1.0, height - 1.0, omega_bounds[1]], budget=int(max_evals),
                          names=("xi", "eta", "omega"))
    run_pymoo(objective, "de", seed=int(seed),
              options={"pop_size": pop_size, "variant": "DE/best/1/bin", "CR": 0.7})
    xi, eta, omega = (float(v) for v in objective.best_point)
    return {"xi": xi, "eta": eta, "omega": omega, "cost": objective.best_value,
            "evaluations": objective.n_evals}
