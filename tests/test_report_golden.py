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
