"""REPORT.md sections of the cloth experiments (reads results, computes nothing)."""

from __future__ import annotations

from replication.report import Section, SummaryRow, fmt


def reference_section(result):
    """Reference runs: files, hashes, and the costs at the true parameters."""
    lines = [
        "Paper: a 17x17 Provot cloth hanging from two corners, K = 4, tau = 0.1 and 0.5, "
        "simulated by the contract in `shared/spec/cloth-model.md` (the paper leaves the "
        "numerics open). Both costs must vanish at the true parameters.",
        "",
        "| run | sha256 (first 16) | small cost at truth | full cost at truth |",
        "|---|---|---|---|",
    ]
    worst = 0.0
    for (name, sha), (label, costs) in zip(result["files"].items(),
                                           result["costs_at_truth"].items()):
        lines.append(f"| `{name}` ({label}) | `{sha[:16]}` | {fmt(costs['small'], 3)} | "
                     f"{fmt(costs['full'], 3)} |")
        worst = max(worst, costs["small"], costs["full"])
    verdict = "replicated" if worst < 1e-20 else "not replicated"
    lines.append("")
    lines.append(f"Largest cost at the true parameters: {fmt(worst, 3)} (zero to round-off "
                 "means below 1e-20 in these units).")
    row = SummaryRow("cost is zero at the true parameters (3.3)", "0", fmt(worst, 3),
                     "< 1e-20", verdict)
    return Section("\n".join(lines), [row])
