"""Checks of a recorded sequence that hold whatever it records (a cloth's positions, image
frames): one engine for every workflow that reads frames as equally spaced in time."""

from __future__ import annotations

import numpy as np


def repeated_frames(frames):
    """Frames identical to the frame before, every value to the last bit, with motion after
    them: a capture that dropped or repeated frames, or frames recorded before the motion
    began. Recorded motion, noise included, never stops for a whole frame and resumes; a
    sequence that comes to rest at its end (a damped cloth settling to the last bit) has no
    such frame, nor one where nothing moves at all (the still checks of each workflow).

    Parameters
    ----------
    frames : (T, ...) array_like
        The sequence, frame first.

    Returns
    -------
    list of int
        The repeating frames, in order (empty when there are none).
    """
    x = np.asarray(frames)
    x = x.reshape(len(x), -1)
    still = np.all(x[1:] == x[:-1], axis=1)   # still[t]: frame t + 1 repeats frame t
    moving = np.flatnonzero(~still)
    if moving.size == 0:
        return []
    return [int(t) + 1 for t in np.flatnonzero(still[:moving[-1]])]


def still_points(frames):
    """Points that never change, every value to the last bit, over the whole sequence while
    other points move: a particle held still (a pin) or a pixel stuck.

    Parameters
    ----------
    frames : (T, P, ...) array_like
        The sequence, frame first, then the points.

    Returns
    -------
    list of int
        Indices of the still points (empty when there are none or nothing moves).
    """
    x = np.asarray(frames)
    x = x.reshape(x.shape[0], x.shape[1], -1)
    still = np.all(x == x[:1], axis=(0, 2))
    if still.all():
        return []
    return [int(p) for p in np.flatnonzero(still)]


def rounding_step(values, smallest):
    """The step ``q`` the values are rounded to (every value ``v0 + k q``, ``k`` an
    integer), or None: positions recorded to a fixed precision (integer millimetres, 0.1
    mm). Steps below ``smallest`` are not looked for (a float's own resolution).

    Parameters
    ----------
    values : array_like
    smallest : float
        The smallest step that counts, in the values' units.
    """
    v = np.unique(np.asarray(values, dtype=float).ravel())
    v = v[np.isfinite(v)]
    if v.size < 3:
        return None
    step = float(np.min(np.diff(v)))
    if not step >= smallest:
        return None
    multiples = (v - v[0]) / step
    if np.max(np.abs(multiples - np.round(multiples))) > 1e-3:
        return None
    return step


def first_few(items, n=8):
    """``"a, b, c"``, or the first ``n`` items then ``", ..."``: how a warning names the
    frames or particles it is about.

    Parameters
    ----------
    items : sequence
        Each written with ``str``.
    n : int
    """
    return ", ".join(str(item) for item in items[:n]) + (", ..." if len(items) > n else "")


def describe_repeats(frames):
    """The start of every repeated-frames warning: ``"N frame(s) (a, b, ...) repeat the
    frame before to the last bit"``, the first 8 frames named.

    Parameters
    ----------
    frames : sequence of int
        What :func:`repeated_frames` returned (not empty).
    """
    return f"{len(frames)} frame(s) ({first_few(frames)}) repeat the frame before to the last bit"
