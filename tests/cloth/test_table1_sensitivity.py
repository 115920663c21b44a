"""Table 1 verdict sensitivity: numerics variants and the study's gather/plot/report code.

The default reading of ``numerics_variants`` must be the suite's model bit for bit; the
study (``table1_reading`` runs -> ``replicate-gather`` CSV -> ``table1_sensitivity``) is run
on a tiny sweep (2 seeds, 3 generations) and its staleness check is exercised.
"""

import csv

import numpy as np
import pytest

from replication.cli import experiment_defaults, run_experiment
from replication.cloth.costs import make_cost
from replication.cloth.identify import problem
from replication.cloth.io import read_trajectory
from replication.cloth.model import params_from_vectors, simulate
from replication.cloth.numerics_variants import (
    Numerics,
    VariantCost,
    regenerate,
    variant_cost,
    variant_rollout,
)
from replication.errors import InputError
from replication.experiments.table1_sensitivity import (
    compose_reading,
    reading_composer,
    sensitivity_study,
)
from replication.provenance import PROJECT_ROOT
from replication.report.table1_sensitivity import sensitivity_section
from replication.sweep import main as gather_main

REFERENCE = PROJECT_ROOT / "synthetic_data" / "cloth" / "reference_tau0.1.npz"
SMOKE = ["ea.generations=3", "n_seeds=2"]


@pytest.fixture(scope="module")
def reference():
    return read_trajectory(REFERENCE)


def _population(trajectory, size=12):
    truth = problem.truth_vector(trajectory)
    rng = np.random.default_rng(3)
    return truth * (1.0 + 0.4 * (rng.random((size, 5)) - 0.5))


def test_default_reading_is_the_suite_model_bit_for_bit(reference):
    params = params_from_vectors(_population(reference))
    for kind in ("small", "full"):
        suite = make_cost(reference, kind)
        variant = VariantCost(reference, suite.frames, Numerics())   # the variant kernel
        assert np.array_equal(variant.frame_errors(params), suite.frame_errors(params))
    truth = params_from_vectors(problem.truth_vector(reference))
    regenerated = regenerate(reference, truth, Numerics())
    assert np.array_equal(regenerated.positions, reference.positions)
    assert np.array_equal(regenerated.flat_velocities(), reference.flat_velocities())
    # a rollout of other parameters too (the reference's truth could hide a branch)
    row = params_from_vectors(_population(reference, 1))
    scene = reference.scene()
    xs, _ = simulate(row, scene, 60)
    mine, _ = variant_rollout(xs[0, 0].copy(), np.zeros_like(xs[0, 0]), row.rest[0], row.k[0],
                              row.tau[0], 61, *Numerics().kernel_args(scene, scene.dt))
    assert np.array_equal(mine, xs[0])
    assert Numerics().is_contract and type(variant_cost(reference, [150], Numerics())) \
        is not VariantCost


def test_variants_change_the_model_and_refuse_bad_settings(reference):
    truth = params_from_vectors(problem.truth_vector(reference))
    base = regenerate(reference, truth, Numerics())
    for numerics in (Numerics(constraint="gauss_seidel"), Numerics(constraint_passes=3),
                     Numerics(damping=1e-4), Numerics(dt=0.001)):
        other = regenerate(reference, truth, numerics)
        assert np.isfinite(other.positions).all()
        assert not np.array_equal(other.positions, base.positions)
        # identified with its own model, the regenerated data costs 0 at the truth
        assert variant_cost(other, [150], numerics)(truth)[0] == 0.0
    # two steps of dt/2 per frame of the suite's data
    assert Numerics(dt=0.001).substeps(0.002) == 2
    with pytest.raises(InputError, match="numerics.dt"):
        Numerics(dt=0.0015).substeps(0.002)
    with pytest.raises(InputError, match="numerics.constraint"):
        Numerics.from_config({"constraint": "red_black"})
    with pytest.raises(InputError, match="unknown"):
        Numerics.from_config({"passes": 2})


@pytest.mark.parametrize("pairs", [
    {}, {"cost.frame": "30"}, {"bounds_preset": "wide", "ea.mutation_scale": "0.2"},
    {"numerics.dt": "null", "numerics.damping": "1e-05", "numerics.dtype": "float32"},
    {"+extra": "1", "restarts": "3"},   # a new key
    {"paper_ea@ea": "paper"},           # a config group: composed in full
])
def test_the_readings_composer_gives_the_full_composition(pairs):
    """The staleness check's quick composer (a copy of the composed experiment with each
    reading's overrides applied) gives exactly what a full Hydra composition gives."""
    composer = reading_composer("table1_reading")
    assert repr(composer(pairs)) == repr(compose_reading("table1_reading", pairs))
    with pytest.raises(Exception, match="Could not override 'nope.x'"):
        composer({"nope.x": "1"})


def _run(sweep, pairs):
    """One sweep job as ``replicate -m`` makes it: folder named by the overrides."""
    folder = sweep / ",".join(f"{k}={v}" for k, v in sorted(pairs.items()))
    config = compose_reading("table1_reading", pairs)
    config["out"] = str(folder)
    config["progress"] = "none"
    run_experiment(config, folder)


def test_study_gathers_plots_reports_and_detects_stale_runs(tmp_path):
    sweep = tmp_path / "multirun"
    smoke = dict(p.split("=") for p in SMOKE)
    for pairs in ({"cost.frame": "150"}, {"cost.frame": "300"},
                  {"numerics.constraint": "gauss_seidel", "numerics.reference": "variant"},
                  {"restarts": "2"}):
        _run(sweep, {**smoke, **pairs})
    table = tmp_path / "sweep.csv"
    assert gather_main([str(sweep), "--output", str(table)]) == 0
    with open(table, newline="") as handle:
        header = next(csv.reader(handle))
    assert "provenance.code_sha256" in header and "provenance.config_sha256" in header

    config = experiment_defaults("table1_sensitivity")
    config.update(data_file=str(table), figure_dir=str(tmp_path / "figures"))
    config["axes"] = [
        {"key": "cost.frame", "values": [150, 300, 450], "label": "frame", "fixed": SMOKE},
        {"key": "numerics.constraint", "values": ["gauss_seidel"], "label": "order",
         "fixed": [*SMOKE, "numerics.reference=variant"]},
        {"key": "restarts", "values": [2], "label": "restarts", "fixed": SMOKE},
    ]
    result = sensitivity_study(config, tmp_path / "out")
    assert result["n_runs"] == 4 and result["staleness"]["n_stale"] == 0
    assert result["n_paper_readings"] == 3 and result["n_beyond_readings"] == 1
    assert [p["found"] for p in result["axes"][0]["points"]] == [True, True, False]
    assert (tmp_path / "figures" / "table1_sensitivity.png").stat().st_size > 0
    assert result["commands"][0] == ("replicate -m experiment=table1_reading "
                                     "cost.frame=150,300,450 ea.generations=3 n_seeds=2")
    section = sensitivity_section({**result, "config": config})
    assert "does not replicate under any of the 3 readings tried" in section.markdown
    assert "Stale" not in section.markdown
    claims = [row.claim for row in section.summary]
    assert claims[0].startswith("Table 1: the 5 best individuals")
    assert all("[sensitivity](#table-1-verdict-sensitivity" in row.verdict
               for row in section.summary)

    # a CSV made by other code is reported stale
    with open(table, newline="") as handle:
        lines = list(csv.DictReader(handle))
    lines[0]["provenance.code_sha256"] = "0" * 64
    with open(table, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(lines[0]))
        writer.writeheader()
        writer.writerows(lines)
    stale = sensitivity_study(config, tmp_path / "out")
    assert stale["staleness"]["n_stale"] == 1 and stale["staleness"]["code"] == 1
    assert "**Stale:** 1 of 4 runs" in sensitivity_section({**stale, "config": config}).markdown


def test_study_without_the_sweep_says_so(tmp_path):
    config = experiment_defaults("table1_sensitivity")
    config.update(data_file=str(tmp_path / "missing.csv"), figure_dir=str(tmp_path))
    result = sensitivity_study(config, tmp_path)
    section = sensitivity_section({**result, "config": config})
    assert "has not been run yet" in section.markdown and len(section.summary) == 3


def test_table1_2_section_links_to_the_sensitivity_heading():
    from replication.report.identify import SENSITIVITY_LINK
    from replication.report.table1_sensitivity import anchor

    title = experiment_defaults("table1_sensitivity")["report"]["title"]
    assert SENSITIVITY_LINK == anchor(title)
