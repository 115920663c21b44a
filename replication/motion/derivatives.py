"""First-order image derivatives for the IRC equation (paper 2.1), with their conventions.

Conventions (written down once, used everywhere):

- ``Ix = dI/dx``: intensity change per pixel along ``x`` (columns, to the right);
  ``Iy = dI/dy`` per pixel along ``y`` (rows, downwards); ``It = dI/dt`` per frame.
- Both frames of a pair are smoothed by the same Gaussian of standard deviation ``sigma``
  pixels. The spatial derivatives are central differences ``(I[x+1] - I[x-1]) / 2`` of the
  average of the two smoothed frames, so they are true derivatives (scikit-image's
  ``sobel`` would give twice this, see docs/pitfalls.md). ``It`` is the difference of the
  smoothed frames. All three are thus estimated at the half-frame ``t + 1/2``.
- A border of ``border`` pixels (default ``ceil(3 sigma) + 1``) is marked invalid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from replication.errors import InputError


@dataclass(frozen=True)
class PixelDerivatives:
    """Derivatives of the selected pixels of one or more frame pairs, as flat arrays.

    ``x, y`` are pixel coordinates; ``gx, gy, gt`` are ``Ix, Iy, It`` there; ``pair`` is
    the index of the frame pair each entry comes from. All arrays have shape ``(n,)``.
    """

    x: np.ndarray
    y: np.ndarray
    gx: np.ndarray
    gy: np.ndarray
    gt: np.ndarray
    pair: np.ndarray

    @property
    def gradient_norm(self):
        """``|grad I|`` per pixel, shape ``(n,)``."""
        return np.hypot(self.gx, self.gy)

    @property
    def normal_flow(self):
        """``|It| / |grad I|`` per pixel, shape ``(n,)``: the speed (pixels/frame) of the
        motion along the gradient; a pixel moves when it is above the noise's."""
        return np.abs(self.gt) / self.gradient_norm

    def __len__(self):
        return self.x.size


def smooth(frame, sigma):
    """Gaussian smoothing of one frame ``(H, W)``; ``sigma = 0`` returns a float copy.

    Parameters
    ----------
    frame : (H, W) ndarray
    sigma : float
        Pixels.
    """
    frame = np.asarray(frame, dtype=float)
    if sigma <= 0:
        return frame.copy()
    return ndimage.gaussian_filter(frame, sigma, mode="nearest")


def spatial_gradient(image):
    """Central-difference ``(Ix, Iy)`` of an ``(H, W)`` image, per pixel (not Sobel)."""
    gy, gx = np.gradient(np.asarray(image, dtype=float))
    return gx, gy


def default_border(sigma):
    """Width of the invalid border for a smoothing of ``sigma`` pixels."""
    return int(math.ceil(3 * sigma)) + 1


def too_small(shape, border, sigma):
    """The refusal of frames of ``shape`` (H, W) that keep no pixel inside ``border``."""
    height, width = shape
    return (f"frames of {height} x {width} pixels: no pixel inside the {border}-pixel border "
            f"that smoothing (sigma={sigma:g}) leaves invalid; expected frames of at least "
            f"{2 * border + 1} x {2 * border + 1} pixels")


def pair_derivatives(frame0, frame1, *, sigma=1.5, border=None):
    """``Ix, Iy, It`` of one frame pair and the mask of valid pixels.

    Parameters
    ----------
    frame0, frame1 : (H, W) ndarray
    sigma : float
        Gaussian pre-smoothing (pixels) applied to both frames.
    border : int or None
        Invalid border width; None means :func:`default_border`.

    Returns
    -------
    gx, gy, gt : (H, W) ndarray of float64
    valid : (H, W) ndarray of bool
    """
    s0, s1 = smooth(frame0, sigma), smooth(frame1, sigma)
    gx, gy = spatial_gradient(0.5 * (s0 + s1))
    gt = s1 - s0
    border = default_border(sigma) if border is None else int(border)
    valid = np.zeros(gx.shape, dtype=bool)
    valid[border: gx.shape[0] - border, border: gx.shape[1] - border] = True
    return gx, gy, gt, valid


def gradient_threshold(gradient_norm, valid, *, relative):
    """The paper's "sufficient gradient norm": ``relative`` times the 99th percentile.

    Relative to the image's own strong gradients, so the same setting works for 8-bit,
    16-bit and float data of any scale.

    Parameters
    ----------
    gradient_norm : (H, W) ndarray
    valid : (H, W) bool ndarray
        Pixels away from the border.
    relative : float
        Fraction of the 99th percentile.
    """
    if not valid.any():
        height, width = gradient_norm.shape
        raise InputError(f"frames of {height} x {width} pixels: no pixel inside the border "
                         "that smoothing leaves invalid; expected larger frames")
    reference = np.percentile(gradient_norm[valid], 99.0)
    return relative * reference


def sequence_derivatives(frames, *, sigma=1.5, relative_threshold=0.15, border=None):
    """Derivatives of every consecutive pair, keeping pixels with a sufficient gradient.

    Parameters
    ----------
    frames : (T, H, W) ndarray, T >= 2
    sigma : float
        Gaussian pre-smoothing (pixels).
    relative_threshold : float
        Keep pixels whose ``|grad I|`` is at least this fraction of the 99th percentile of
        ``|grad I|`` over valid pixels (per pair).

    Returns
    -------
    PixelDerivatives
        The kept pixels of all pairs, pair by pair, each in row-major order.
    """
    parts = []
    for t in range(frames.shape[0] - 1):
        gx, gy, gt, valid = pair_derivatives(frames[t], frames[t + 1], sigma=sigma,
                                             border=border)
        if not valid.any():
            b = default_border(sigma) if border is None else int(border)
            raise InputError(too_small(frames.shape[1:], b, sigma))
        norm = np.hypot(gx, gy)
        keep = valid & (norm >= gradient_threshold(norm, valid, relative=relative_threshold))
        keep &= norm > 0
        y, x = np.nonzero(keep)
        parts.append((x.astype(float), y.astype(float), gx[keep], gy[keep], gt[keep],
                      np.full(x.size, t, dtype=np.int64)))
    columns = [np.concatenate(c) for c in zip(*parts)]
    return PixelDerivatives(*columns)
