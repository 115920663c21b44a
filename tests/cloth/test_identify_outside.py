"""The identifier's blind study on outside data (cloth_identify_outside): the draw, the
scoring against the generator's truth, the summary, and refused settings."""

import re

import numpy as np
import pytest

from replication.cli import run_experiment
from replication.errors import InputError
from replication.experiments import outside_identify as study_module
from tests.cloth.test_identify_cli import composed


def _study(**changes):
    return {**composed("cloth_identify_outside")["study"], **changes}


def test_draw_is_seeded_wide_and_has_noise_free_datasets():
    study = _study(n_datasets=200)
    specs = study_module.draw_specs(study, 5)
    assert specs == study_module.draw_specs(study, 5)
    K = np.array([s["K"] for s in specs])
    tau = np.array([s["tau"] for s in specs])
    noise = np.array([s["noise_h"] for s in specs])
    assert K.min() >= 0.1 and K.max() <= 10.0 and tau.min() >= 0.01 and tau.max() <= 1.0
    # log-uniform over two decades: about half of each below the middle decade's edge
    assert 0.35 < np.mean(K < 1.0) < 0.65 and 0.35 < np.mean(tau < 0.1) < 0.65
    assert 0.1 < np.mean(noise == 0.0) < 0.4 and noise.max() > 1e-2
    assert all(s["effects"] == [] for s in specs)
    assert np.all(np.isfinite(noise))
    none_zero = study_module.draw_specs(_study(n_datasets=20, noise_zero_share=0.0), 5)
    assert all(s["noise_h"] > 0 for s in none_zero)


def test_an_exact_dataset_is_identified_and_scored_against_the_generators_truth(tmp_path):
    config = composed("cloth_identify_outside")
    spec = {"n_frames": 170, "K": 4.0, "tau": 0.5, "noise_h": 0.0, "seed": 3, "effects": []}
    run = {k: v for k, v in config.items() if k not in ("report", "study")}
    row = study_module.run_one(spec, {**run, "methods": ["structured"]}, tmp_path)
    assert list(tmp_path.iterdir()) == []    # the dataset file is removed
    (answer,) = study_module.answers_of([row], "structured")
    assert answer["refused"] is None and answer["success"] and not answer["truth_cheaper"]
    assert answer["relative_errors"]["K"] == pytest.approx(0.0, abs=1e-6)
    assert answer["truth_cost"] < 1e-20 and answer["truth_in_bounds"]
    assert answer["constraint_share"] > 0.0 and answer["K"] == 4.0
    assert answer["warnings"] == [] and not answer["warned"]


def test_summary_counts_failures_warned_silent_and_by_regime():
    def row(share, success, warned, cheaper=False, noise=1e-3):
        return {"constraint_share": share, "success": success, "warned": warned,
                "max_abs_error": 0.001 if success else 0.5 + share,
                "truth_cheaper": cheaper, "truth_in_bounds": True, "refused": None,
                "noise_h": noise, "wall_seconds": 1.0}
    rows = [row(0.01, True, False), row(0.2, False, True, cheaper=True),
            row(0.2, False, False, noise=0.0), row(0.9, True, True), row(0.9, False, False),
            {**row(0.9, False, False, noise=1e-5), "refused": "cannot be read"}]
    regimes = [{"label": "rare", "max_share": 0.05}, {"label": "often", "max_share": 0.5},
               {"label": "always", "max_share": 1.0}]
    summary = study_module.summarise(rows, regimes, 0.01)
    assert summary["all"]["n"] == 6 and summary["all"]["success_rate"] == pytest.approx(1 / 3)
    # the refused answer is a failure, not a silent one
    assert summary["all"]["failed_warned"] == 1 and summary["all"]["failed_silent"] == 2
    assert summary["refused"] == 1 and summary["all"]["n_failed"] == 4
    assert summary["all"]["failed_truth_cheaper"] == 1
    assert summary["all"]["succeeded_warned"] == 1
    assert summary["all"]["unwarned_max_abs_error"] == pytest.approx(1.4)   # share 0.9
    assert [r["n"] for r in summary["by_regime"]] == [1, 2, 3]
    assert [r["share_range"] for r in summary["by_regime"]] == [[0.0, 0.05], [0.05, 0.5],
                                                               [0.5, 1.0]]
    assert summary["noise_free"]["n"] == 1 and summary["noise_free"]["failed_silent"] == 1
    # noise bands at the identifier's warning levels (3e-4, 3e-3 h): 0 and 1e-5 in the first
    assert [b["n"] for b in summary["by_noise"]] == [2, 4, 0]
    assert summary["by_noise"][0]["noise_h_range"] == [0.0, 3e-4]
    assert summary["by_noise"][2]["noise_h_range"] == [3e-3, None]
    assert [r["n"] for r in summary["by_regime_quiet"]] == [0, 1, 1]


@pytest.mark.parametrize("override, message", [
    ("study.n_datasets=0", "study.n_datasets=0: expected an integer >= 1"),
    ("study.K_range=[1.0,0.5]", "study.K_range=[1.0, 0.5]"),
    ("study.frames_range=[100,200]", "the shortest dataset (100 frames) does not hold the "
                                      "cost: cost.frame=150 (small cost)"),
    ("study.frames_range=[160,200] cost.kind=full cost.start=150",
     "the shortest dataset (160 frames) does not hold the cost: cost.start=150"),
    ("study.noise_zero_share=1.5", "study.noise_zero_share=1.5"),
    ("study.regimes=[{label:a,max_share:0.5}]", "max_share increasing to 1"),
    ("model=18", "expected model=5"),
    ("methods=[structured,nope]", "method='nope': expected one of"),
])
def test_settings_it_cannot_use_are_refused_before_any_work(tmp_path, override, message):
    out = tmp_path / "out"
    config = composed("cloth_identify_outside", *override.split(), f"out={out}",
                      f"figure_dir={tmp_path / 'fig'}")
    with pytest.raises(InputError, match=re.escape(message)):
        run_experiment(config, out)
    assert not (out / "result.json").exists() and not (tmp_path / "fig").exists()
