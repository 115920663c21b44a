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
