"""Frames of a textured plane turning exactly, and its exact derivatives (omega-bias study).

This module is deliberately independent of the methods it serves to test: it imports only
numpy and the standard library's ``math``, so a bug of the derivatives or of the vote
cannot hide itself in the test data.

The scene fills the whole frame (no object edge, no static background): a texture made of
``count`` plane waves ``a cos(2 pi f . q + phi)`` whose frequencies ``|f|`` (cycles per
pixel) are spread evenly in log-frequency over a band ``[f0 / sqrt(band), f0 sqrt(band)]``
around ``f0 = 1 / wavelength``, in random directions, with equal amplitudes scaled to a
standard deviation of ``contrast`` around ``mean``. Frame ``t`` shows the texture turned
by ``omega t`` about ``(xi, eta)``: a point of the texture at ``q`` is at
``c + R(omega t) (q - c)``, ``R(a) = [[cos a, -sin a], [sin a, cos a]]``, ``x`` the column,
``y`` the row (docs/data-formats.md), so its velocity is ``omega (-(y - eta), x - xi)``,
the paper's IRC equation. Pixels sample the scene at their centres ``(x, y) = (column,
row)``; every frequency is below the Nyquist limit of 0.5 cycle per pixel, so the samples
are exact.

:func:`exact_derivatives` gives ``Ix, Iy, It`` of the scene smoothed by a continuous
Gaussian of ``sigma`` pixels, at any time ``t`` (an instantaneous ``It``): they verify the
IRC equation exactly.
"""

import math

import numpy as np


def texture_waves(wavelength, *, rng, count=60, band=2.0, contrast=0.12):
    """The waves of one texture.

    Parameters
    ----------
    wavelength : float
        Pixels; the centre of the band, ``f0 = 1 / wavelength`` cycles per pixel.
    rng : numpy.random.Generator
    count : int
    band : float
        Ratio of the highest to the lowest frequency.
    contrast : float
        Standard deviation of the texture (intensity units).

    Returns
    -------
    waves : dict
        ``frequency (count, 2)`` cycles per pixel (``x``, ``y``), ``amplitude (count,)``,
        ``phase (count,)``.
    """
    f0 = 1.0 / float(wavelength)
    low, high = f0 / math.sqrt(band), f0 * math.sqrt(band)
    if high >= 0.5:
        raise ValueError(f"wavelength={wavelength}, band={band}: the highest frequency "
                         f"{high:.3g} cycle/pixel is not below 0.5; expected a longer "
                         "wavelength or a narrower band")
    radius = np.exp(rng.uniform(math.log(low), math.log(high), count))
    angle = rng.uniform(0.0, 2.0 * math.pi, count)
    phase = rng.uniform(0.0, 2.0 * math.pi, count)
    amplitude = np.full(count, contrast / math.sqrt(0.5 * count))
    frequency = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    return {"frequency": frequency, "amplitude": amplitude, "phase": phase}


def _turned(waves, *, xi, eta, angle):
    """Frequencies ``(k, 2)`` and phases ``(k,)`` of the texture turned by ``angle``.

    The texture seen at ``p`` is ``T(c + R(-angle) (p - c))``; a wave ``f . q`` becomes
    ``(R(angle) f) . p + f . c - (R(angle) f) . c``.
    """
    c, s = math.cos(angle), math.sin(angle)
    frequency = waves["frequency"] @ np.array([[c, -s], [s, c]]).T
    centre = np.array([xi, eta])
    phase = waves["phase"] + 2.0 * math.pi * (waves["frequency"] @ centre
                                              - frequency @ centre)
    return frequency, phase


def _sum_waves(side, frequency, weights):
    """``Re sum_k weights_k exp(2 pi i f_k . p)`` on the ``side x side`` pixel grid."""
    pixel = np.arange(side, dtype=float)
    ex = np.exp(2j * math.pi * frequency[:, 0:1] * pixel[None, :])      # (k, W)
    ey = np.exp(2j * math.pi * frequency[:, 1:2] * pixel[None, :])      # (k, H)
    return np.real(ey.T @ (weights[:, None] * ex))


def render(waves, *, side, xi, eta, omega, times, mean=0.5):
    """Frames of the texture turning about ``(xi, eta)`` at ``omega`` rad/frame.

    Parameters
    ----------
    waves : dict
        From :func:`texture_waves`.
    side : int
        Frame side, pixels.
    xi, eta : float
        Rotation centre, pixels (``x`` column, ``y`` row).
    omega : float
        Rad/frame.
    times : sequence of float
        Frame times.

    Returns
    -------
    frames : (len(times), side, side) ndarray of float64
    """
    frames = []
    for t in times:
        frequency, phase = _turned(waves, xi=xi, eta=eta, angle=omega * t)
        frames.append(mean + _sum_waves(side, frequency, waves["amplitude"]
                                        * np.exp(1j * phase)))
    return np.stack(frames)


def exact_derivatives(waves, *, side, xi, eta, omega, t, sigma):
    """``Ix, Iy, It`` of the scene smoothed by a Gaussian of ``sigma`` pixels, at time ``t``.

    The smoothing multiplies a wave of frequency ``f`` by ``exp(-2 pi^2 sigma^2 |f|^2)``;
    ``It = -(Ix vx + Iy vy)`` with the velocity ``v = omega (-(y - eta), x - xi)`` of the
    rigid rotation, the time derivative at ``t`` itself (no finite difference).

    Parameters
    ----------
    waves : dict
    side : int
    xi, eta, omega : float
    t : float
        Time (frames).
    sigma : float
        Pixels.

    Returns
    -------
    gx, gy, gt : (side, side) ndarray of float64
    """
    frequency, phase = _turned(waves, xi=xi, eta=eta, angle=omega * t)
    gain = np.exp(-2.0 * math.pi ** 2 * sigma ** 2 * np.sum(frequency ** 2, axis=1))
    weights = waves["amplitude"] * gain * np.exp(1j * phase) * 2j * math.pi
    gx = _sum_waves(side, frequency, weights * frequency[:, 0])
    gy = _sum_waves(side, frequency, weights * frequency[:, 1])
    rows, cols = np.mgrid[0:side, 0:side].astype(float)
    vx, vy = -omega * (rows - eta), omega * (cols - xi)
    return gx, gy, -(gx * vx + gy * vy)
