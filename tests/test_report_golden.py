"""REPORT.md is what the committed results give: built again here, it must be the same text
(a number typed into REPORT.md, or a result changed without rebuilding it, fails)."""

from replication.provenance import PROJECT_ROOT
from replication.report.build import build_report


def test_report_is_built_from_the_committed_results():
    built = build_report(PROJECT_ROOT / "results")
    committed = (PROJECT_ROOT / "REPORT.md").read_text()
    if built != committed:
        lines = [(i, a, b) for i, (a, b) in
                 enumerate(zip(built.splitlines(), committed.splitlines()), 1) if a != b]
        first = lines[0] if lines else ("length", len(built), len(committed))
        raise AssertionError(f"REPORT.md differs from the results at line {first[0]}:\n"
                             f"built:     {first[1]}\ncommitted: {first[2]}\n"
                             "rebuild it: python -m replication.report.build")


def test_the_discrepancy_example_section_lists_vectors_and_leaves_matrices_out():
    """A named effect's covariance and a mass map (lists of lists) stay in result.json;
    the table shows scalars and vectors."""
    import json

    from replication.report.discrepancy import example_section

    result = json.loads((PROJECT_ROOT / "results/discrepancy_example/result.json").read_text())
    effect = result["named_effects"][0]
    effect["parameters"].update(covariance=[[1e-6, 0.0], [0.0, 1e-6]],
                                relative_mass=[[1.0, 1.1], [0.9, 1.0]], direction=[0.0, 1.0])
    text = example_section(result).markdown
    row = next(line for line in text.splitlines() if line.startswith("| with effect"))
    assert "direction = (0, 1)" in row
    assert "covariance" not in row and "relative_mass" not in row


def test_the_fig11_paragraph_quotes_the_configured_costs_and_needs_two_sets():
    """The paragraph on the paper's error levels quotes the costs of the sets the run
    re-simulated (a user's own sets included), not numbers typed into the report."""
    from replication.report.cloth import reconstruction_section

    def row(label, cost, rms):
        return {"label": label, "paper_cost": cost, "small": 1.0, "full": 1.0,
                "rms_error_h": rms, "final_error_h": rms}

    result = {"data": "d.npz", "figures": ["f.png", "f.gif"],
              "config": {"visible_error_h": 0.5},
              "reconstructions": [row("mine", 0.25, 0.1), row("other", 0.75, 2.0)]}
    text = reconstruction_section(result).markdown
    assert "(cost 0.25)" in text and "(cost 0.75)" in text
    result["reconstructions"] = result["reconstructions"][:1]
    assert "The paper puts the two" not in reconstruction_section(result).markdown


def test_rates_over_datasets_carry_their_wilson_interval():
    """20 exact answers of 25: 80%, and the 95% Wilson interval from its closed form
    (p + z^2/2n +- z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n), z = 1.95996."""
    import math

    from replication.report.discrepancy import _pct_of

    n, p, z = 25, 0.8, 1.959964
    centre, half = p + z * z / (2 * n), z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    low, high = ((centre - half) / (1 + z * z / n), (centre + half) / (1 + z * z / n))
    assert _pct_of(0.8, 25) == (f"80% of 25 (95% interval {100 * low:.0f}-"
                                f"{100 * high:.0f}%)") == "80% of 25 (95% interval 61-91%)"
    assert _pct_of(None, 25) == "n/a" and _pct_of(0.5, 0) == "50%"
