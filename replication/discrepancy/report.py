"""REPORT.md section of the blind discrepancy study (reads results, computes nothing)."""

from __future__ import annotations

from replication.report import Section, SummaryRow, fmt


def _pct(value):
    return "n/a" if value is None else f"{100 * value:.0f}%"


def _verdict(ok):
    return "beyond the paper (met)" if ok else "beyond the paper (not met)"


def blind_section(result):
    """Correct-name rate, confusion matrix, false names, gap shrink, coefficient errors."""
    s = result["summary"]
    config = result["config"]["study"]
    lines = [
        "Not in the paper: the suite's own workflow (issue 6). Each dataset hides one effect "
        "(or none, or a `gust` that is not in the library), with magnitude, position noise "
        f"(log-uniform in {config['noise_range'][0]:g}..{config['noise_range'][1]:g} h) and "
        "seed drawn at random; the workflow sees positions only. "
        f"{s['n_datasets']} datasets of {config['n_frames']} frames "
        f"({s['n_effect_free']} effect-free). Moderate SNR means noise <= "
        f"{s['moderate_noise_h']:g} h.",
        "",
        "| measure | goal | measured |",
        "|---|---|---|",
        f"| correct name, moderate SNR (n={s['n_moderate']}) | >= 90% | "
        f"{_pct(s['correct_rate_moderate_snr'])} |",
        f"| correct name, all effects | | {_pct(s['correct_rate_all_effects'])} |",
        f"| false names on effect-free data (n={s['n_effect_free']}) | <= 5% | "
        f"{_pct(s['false_name_rate_effect_free'])} |",
        f"| outside-library effect reported unexplained | | "
        f"{_pct(s['outside_effect_reported_unexplained'])} |",
        f"| median gap shrink (held-out rollout, correct names) | >= 5x | "
        f"{fmt(s['gap_shrink_median'], 3)}x |",
        f"| median coefficient error (correct names) | <= 10% | "
        f"{_pct(s['coefficient_error_median'])} |",
        f"| coefficients within 10% | | {_pct(s['coefficient_within_10pct'])} |",
        f"| analysis time per dataset (median / max) | | "
        f"{fmt(s['wall_seconds_median'], 3)} s / {fmt(s['wall_seconds_max'], 3)} s |",
        "",
        "Confusion matrix (rows hidden, columns called):",
        "",
        "| hidden \\ called | " + " | ".join(s["classes"]) + " |",
        "|---|" + "---|" * len(s["classes"]),
    ]
    for hidden in s["classes"]:
        counts = [str(s["confusion"][hidden][called]) for called in s["classes"]]
        lines.append(f"| {hidden} | " + " | ".join(counts) + " |")
    lines += ["", f"![blind study](../{result['figure']})" if result.get("figure") else ""]
    moderate = s["correct_rate_moderate_snr"]
    false_rate = s["false_name_rate_effect_free"]
    shrink = s["gap_shrink_median"]
    error = s["coefficient_error_median"]
    rows = [
        SummaryRow("missing effect named, moderate SNR (issue 6)", "not in paper",
                   _pct(moderate), ">= 90%", _verdict(moderate is not None and moderate >= 0.9)),
        SummaryRow("false names on effect-free data (issue 6)", "not in paper",
                   _pct(false_rate), "<= 5%",
                   _verdict(false_rate is not None and false_rate <= 0.05)),
        SummaryRow("median held-out gap shrink (issue 6)", "not in paper",
                   f"{fmt(shrink, 3)}x", ">= 5x", _verdict(shrink is not None and shrink >= 5)),
        SummaryRow("median coefficient error (issue 6)", "not in paper", _pct(error),
                   "<= 10%", _verdict(error is not None and error <= 0.1)),
    ]
    return Section("\n".join(lines), rows)
