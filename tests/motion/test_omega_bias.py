"""The omega-bias study: its independent test data, the sign of the bias it documents, and
its runner and REPORT section on a tiny config."""

import ast
import inspect

import numpy as np
import pytest

from replication.errors import InputError
from replication.experiments import omega_bias
from replication.motion import wave_data
from replication.motion.derivatives import sequence_derivatives
from replication.report import omega_bias as omega_bias_report

SIDE, CENTRE, SIGMA = 48, (22.0, 26.0), 1.5
GRID = {"low": -0.2, "high": 0.4, "step": 0.01}


def test_the_generator_imports_none_of_the_code_it_tests():
    tree = ast.parse(inspect.getsource(wave_data))
    imported = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import)
                for alias in node.names}
    imported |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert imported == {"math", "numpy"}


@pytest.fixture(scope="module")
def scene():
    waves = wave_data.texture_waves(6.0, rng=np.random.default_rng(1), count=40)
    frames = wave_data.render(waves, side=SIDE, xi=CENTRE[0], eta=CENTRE[1], omega=-0.03,
                              times=(0.0, 1.0, 2.0))
    return waves, frames


def test_exact_derivatives_verify_the_irc_equation_and_the_frames(scene):
    waves, _ = scene
    omega = -1e-4      # small enough for a finite difference to be the derivative
    gx, gy, gt = wave_data.exact_derivatives(waves, side=SIDE, xi=CENTRE[0], eta=CENTRE[1],
                                             omega=omega, t=0.5, sigma=0.0)
    rows, cols = np.mgrid[0:SIDE, 0:SIDE].astype(float)
    irc_residual = -omega * gx * (rows - CENTRE[1]) + omega * gy * (cols - CENTRE[0]) + gt
    np.testing.assert_allclose(irc_residual, 0.0, atol=1e-15)
    frames = wave_data.render(waves, side=SIDE, xi=CENTRE[0], eta=CENTRE[1], omega=omega,
                              times=(0.0, 1.0))
    np.testing.assert_allclose(frames[1] - frames[0], gt, atol=1e-3 * np.abs(gt).max())


def test_the_suite_reading_is_the_suites_derivatives(scene):
    _, frames = scene
    mine = omega_bias.voting_pixels(*omega_bias.derivative_fields(frames, "suite", sigma=SIGMA),
                                    sigma=SIGMA, relative_threshold=0.3)
    theirs = sequence_derivatives(frames[:2], sigma=SIGMA, relative_threshold=0.3)
    for key in ("x", "y", "gx", "gy", "gt"):
        np.testing.assert_array_equal(getattr(mine, key), getattr(theirs, key))


def _bias(frames, fields):
    pixels = omega_bias.voting_pixels(*fields, sigma=SIGMA, relative_threshold=0.3)
    return omega_bias.peak_bias(pixels, -0.03, CENTRE, shape=frames.shape[1:],
                                grid=GRID)["bias_pct"]


def test_the_peak_overestimates_omega_through_the_derivatives_not_the_vote(scene):
    waves, frames = scene
    exact = wave_data.exact_derivatives(waves, side=SIDE, xi=CENTRE[0], eta=CENTRE[1],
                                        omega=-0.03, t=0.5, sigma=SIGMA)
    suite = _bias(frames, omega_bias.derivative_fields(frames, "suite", sigma=SIGMA))
    gaussian = _bias(frames, omega_bias.derivative_fields(frames, "gaussian", sigma=SIGMA))
    three = _bias(frames, omega_bias.derivative_fields(frames, "gaussian_central3",
                                                       sigma=SIGMA))
    assert suite > 5.0                        # |omega| too large, as the report says
    assert 0.0 < gaussian < suite             # the central difference's share removed
    assert three < 0.0                        # the three-frame difference errs the other way
    assert abs(_bias(frames, exact)) <= 1.0   # exact derivatives: no bias from the vote


def test_leading_order_terms_have_the_documented_signs(scene):
    waves, _ = scene
    exact = omega_bias.voting_pixels(*wave_data.exact_derivatives(
        waves, side=SIDE, xi=CENTRE[0], eta=CENTRE[1], omega=-0.03, t=0.5, sigma=SIGMA),
        sigma=SIGMA, relative_threshold=0.3)
    terms = omega_bias.leading_order(waves, exact, CENTRE, -0.03, sigma=SIGMA)
    assert terms["spatial_pct"] > terms["temporal_pct"] > 0 > terms["chord_pct"]
    assert terms["chord_pct"] == pytest.approx(-100 * 0.03 ** 2 / 24, rel=1e-3)


def test_a_wavelength_at_the_nyquist_limit_is_refused():
    with pytest.raises(ValueError, match="not below 0.5"):
        wave_data.texture_waves(2.5, rng=np.random.default_rng(0))


TINY = {
    "seed": 0, "single_result": "results/motion_single", "sequences_dir": "synthetic_data/motion",
    "paper_like": "paper_like", "side": 48, "centre": [0.45, 0.55],
    "texture": {"count": 40, "band": 2.0, "contrast": 0.12}, "texture_seed": 0,
    "reference": {"omega": -0.03, "wavelength": 6.0}, "speeds": [-0.03],
    "wavelengths": [6.0], "noise_levels_255": [0.0, 4.0], "noise_seeds": 1,
    "collapse_factor": 0.5, "cells": [1.0], "cell_noise_255": 4.0, "grid": GRID,
    "paper_grid": {"low": -0.1, "high": 0.2, "step": 0.1}, "tolerance_pct": 1.0,
    "max_speed": 0.05, "threads": 1,
    "report": {"title": "Why the best peak overestimates omega (paper 2.2)"},
}


def test_runner_and_section_on_a_tiny_config(tmp_path):
    config = dict(TINY, figure_dir=str(tmp_path / "figures"))
    result = omega_bias.omega_bias_study(config, tmp_path)
    result["config"] = config
    terms = result["decomposition"]["controlled"]
    assert terms["spatial_filter_pct"] > 0 and abs(terms["accumulator_pct"]) <= 1.0
    section = omega_bias_report.omega_bias_section(result)
    assert "**Answer.**" in section.markdown and "| `gaussian_central3` |" in section.markdown
    (row,) = section.summary
    assert row.claim == "best peak gives omega (2.2, Fig. 2)"
    assert "(#why-the-best-peak-overestimates-omega-paper-22)" in row.verdict
    assert (tmp_path / "figures" / "motion_omega_bias.png").is_file()


def test_a_zero_speed_is_refused(tmp_path):
    with pytest.raises(InputError, match="non-zero"):
        omega_bias.omega_bias_study(dict(TINY, speeds=[0.0]), tmp_path)
