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
