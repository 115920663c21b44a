"""REPORT.md sections of the discrepancy studies (read results and the committed sweep CSV;
no fitting, only counting)."""

from __future__ import annotations

from scipy.stats import norm

from replication.experiments.discrepancy_outside import (
    SWEEP_CSV,
    outside_study,
    rows_from_gathered,
    summarise,
)
from replication.provenance import accepted_code_hashes
from replication.report.build import Section, SummaryRow, fmt
from replication.testdata import cloth_outside as og

# |error| / standard error of exact standard errors and normal errors: the shares within 1
# and 2, and the median
EXACT_WITHIN = {"1": 2 * norm.cdf(1.0) - 1, "2": 2 * norm.cdf(2.0) - 1}
EXACT_MEDIAN = norm.ppf(0.75)

BEYOND = "beyond the paper"


def _pct(value):
    if value is None:
        return "n/a"
    return f"{100 * value:.0f}%" if value >= 0.1 or value == 0 else f"{100 * value:.2g}%"


def _pct_of(rate, n):
    """``rate`` of ``n`` datasets with its 95% Wilson interval (scipy's ``binomtest``): a
    rate over a few dozen datasets moves by several points when one answer changes."""
    if rate is None or not n:
        return _pct(rate)
    from scipy.stats import binomtest

    interval = binomtest(round(rate * n), n).proportion_ci(0.95, method="wilson")
    return (f"{_pct(rate)} of {n} (95% interval {100 * interval.low:.0f}-"
            f"{100 * interval.high:.0f}%)")


def _goal(text, ok):
    return f"{text} (goal {'met' if ok else 'not met'})"


def _by_composition(rows, limit):
    """Datasets above the detection limit grouped by what they hide."""
    above = [r for r in rows if r["kinds"] and float(r["min_snr"]) >= limit]
    return [("one effect", [r for r in above if len(r["kinds"]) == 1]),
            ("two library effects", [r for r in above if len(r["kinds"]) == 2
                                     and not r["expected_unexplained"]]),
            ("a library effect and an outside one",
             [r for r in above if len(r["kinds"]) == 2 and r["expected_unexplained"]
              and r["expected_names"]]),
            ("two outside effects", [r for r in above if len(r["kinds"]) == 2
                                     and not r["expected_names"]])]


def _share(count, total):
    """``count`` of ``total`` as a percentage (``-`` for none)."""
    return f"{count} ({_pct(count / total)})" if total else "-"


def _warned_rows(s, where):
    """Table rows: wrong and exact answers with a warning, and with the detection-limit
    caveat that every 'none' at a high limit carries (counted apart)."""
    n_exact = s["n_datasets"] - s["n_wrong"]
    return [f"| wrong answers with a warning, the detection-limit caveat aside ({where}"
            f"n={s['n_wrong']}) | | {_share(s['wrong_warned'], s['n_wrong'])} |",
            f"| wrong answers with the detection-limit caveat (n={s['n_wrong']}) | | "
            f"{_share(s['wrong_caveat'], s['n_wrong'])} |",
            f"| exact answers with a warning, the caveat aside (n={n_exact}) | | "
            f"{_share(s['exact_warned'], n_exact)} |",
            f"| exact answers with the detection-limit caveat (n={n_exact}) | | "
            f"{_share(s['exact_caveat'], n_exact)} |"]


def outside_section(result):
    """The blind study on outside data: exact answers, false names, gap, time."""
    return _outside(result, sweep=True, scope="")


def outside_wide_section(result):
    """The same blind study over the whole range of the identification bounds (no sweep)."""
    return _outside(result, sweep=False, scope=", K and tau over the whole range of the bounds")


def _outside(result, *, sweep, scope):
    s = result["summary"]
    config = result["config"]["study"]
    limit = s["detection_snr"]
    lines = [
        "Not in the paper. Datasets made by an independent generator "
        "(`replication/testdata/cloth_outside.py`, which imports nothing of the package: the "
        "cloth model written again from the contract, each effect from its physical "
        "definition), written to `.npz` files and read back like a user's file. "
        f"{s['n_datasets']} datasets drawn at random (seed {result['config']['seed']}): "
        f"{config['frames_range'][0]}..{config['frames_range'][1]} frames, K "
        f"{config['K_range'][0]:g}..{config['K_range'][1]:g} and tau "
        f"{config['tau_range'][0]:g}..{config['tau_range'][1]:g} "
        f"({'log-uniform' if config.get('log_uniform') else 'uniform'}), position noise "
        "exactly 0 "
        "or log-uniform 1e-4..5e-3 h, 0, 1 or 2 effects, effect sizes 10^u times a nominal "
        f"size with u in {config['size_decades'][0]:g}..{config['size_decades'][1]:g}; "
        f"{s['n_effect_free']} effect-free ({s['n_effect_free_noise_free']} of them "
        f"noise-free), {s['n_two_effects']} with two effects, {s['n_outside']} with an effect "
        "outside the library (a gust oscillating in time, a swirling force field, "
        "stiffening springs).",
        "",
        "An answer is exact when the named effects are exactly those present (each once, "
        "nothing else) and 'unexplained' is reported exactly when an effect outside the "
        "library is present. The detection limit is stated, not fitted per dataset: SNR of "
        f"the weakest effect present >= {limit:g}, where SNR is the generator's matched-filter "
        "ratio (the effect's one-step displacements on particle-frames the constraint did "
        "not move, against the one-step noise); noise-free data have infinite SNR.",
        "",
        "| measure | goal | measured |",
        "|---|---|---|",
        f"| exact answers, all datasets above the detection limit (n={s['n_above_limit']}, "
        f"effect-free included) | >= 90% | {_pct(s['exact_rate_above_limit'])} |",
        f"| exact answers, datasets with effects above the limit "
        f"(n={s['n_effects_above_limit']}) | | {_pct(s['exact_rate_effects_above_limit'])} |",
        f"| exact answers, below the limit (n={s['n_below_limit']}) | | "
        f"{_pct(s['exact_rate_below_limit'])} |",
        f"| exact answers, whole set (n={s['n_datasets']}) | | {_pct(s['exact_rate_all'])} |",
        f"| false names on effect-free data (n={s['n_effect_free']}) | 0 | "
        f"{s['false_names_effect_free']} |",
        f"| false 'unexplained' on effect-free data | 0 | "
        f"{s['false_unexplained_effect_free']} |",
        f"| valid datasets refused | 0 | {s['refused']} |",
        *_warned_rows(s, "whole set, "),
        f"| median held-out gap shrink (exact answers naming effects, "
        f"n={s['n_gap_shrink']}) | >= 5x | {fmt(s['gap_shrink_median'], 3)}x |",
        f"| analysis time per dataset (median / max) | | "
        f"{fmt(s['wall_seconds_median'], 3)} s / {fmt(s['wall_seconds_max'], 3)} s |",
        "",
        "| kind | expected answer | datasets | exact (all) | above limit | exact above limit |",
        "|---|---|---|---|---|---|",
    ]
    expected = {kind: spec["expected"] for kind, spec in og.KINDS.items()}
    for kind, k in s["by_kind"].items():
        lines.append(f"| {kind} | {expected.get(kind, '')} | {k['n_all']} | "
                     f"{_pct(k['exact_all'])} | {k['n_above']} | {_pct(k['exact_above'])} |")
    # result.json stores an infinite SNR (noise-free data) as the string "inf"
    wrong = [r for r in result["datasets"] if not r["exact"] and float(r["min_snr"]) >= limit]
    if wrong:
        lines += ["", "Wrong answers above the detection limit (hidden -> called):", ""]
        for r in wrong:
            hidden = ", ".join(r["kinds"]) or "none"
            called = ", ".join(r["named"]) or "none"
            lines.append(f"- {hidden} (noise {r['noise_h']:.2g} h, {r['n_frames']} frames, "
                         f"SNR {fmt(float(r['min_snr']), 3)}) -> {called}"
                         f"{' + unexplained' if r['unexplained'] else ''}"
                         f"{'; warned: ' + r['warnings'][0] if r.get('warnings') else ''}")
    lines += ["", f"![outside blind study]({result['figure']})" if result.get("figure") else "",
              "", f"Regenerate: `replicate experiment={result['experiment']} force=true`."]
    pooled_rows, runs = rows_from_gathered() if sweep else ([], [])
    pooled = summarise(pooled_rows, limit) if pooled_rows else None
    if pooled:
        seeds = ", ".join(str(r["seed"]) for r in runs)
        accepted = accepted_code_hashes(f"{outside_study.__module__}:{outside_study.__name__}")
        stale = [r for r in runs if r["code_sha256"] not in accepted]
        lines += [
            "", f"**Documented sweep** (seeds {seeds}: {pooled['n_datasets']} more datasets "
            "drawn the same way, none of them seen while the workflow was tuned (on the set "
            "above and on separate tuning sets); gathered CSV committed as "
            f"`{SWEEP_CSV}`, pooled here):", "",
            *([f"**Stale:** {len(stale)} of {len(runs)} runs of the sweep were made by other "
               "code than the current runner's (code hash, or no provenance in the CSV); "
               "re-run the sweep for numbers of the current code.", ""] if stale else []),
            "| measure | goal | measured |", "|---|---|---|",
            f"| exact answers above the detection limit (n={pooled['n_above_limit']}) | "
            f">= 90% | {_pct(pooled['exact_rate_above_limit'])} |",
            f"| exact answers, datasets with effects above the limit "
            f"(n={pooled['n_effects_above_limit']}) | | "
            f"{_pct(pooled['exact_rate_effects_above_limit'])} |",
            f"| exact answers, below the limit (n={pooled['n_below_limit']}) | | "
            f"{_pct(pooled['exact_rate_below_limit'])} |",
            f"| exact answers, whole set (n={pooled['n_datasets']}) | | "
            f"{_pct(pooled['exact_rate_all'])} |",
            f"| false names / false 'unexplained' on effect-free data "
            f"(n={pooled['n_effect_free']}, {pooled['n_effect_free_noise_free']} noise-free) | "
            f"0 / 0 | {pooled['false_names_effect_free']} / "
            f"{pooled['false_unexplained_effect_free']} |",
            f"| valid datasets refused | 0 | {pooled['refused']} |",
            *_warned_rows(pooled, ""),
            *[f"| exact answers above the limit, {label} (n={len(subset)}) | | "
              f"{_pct(sum(r['exact'] for r in subset) / len(subset)) if subset else 'n/a'} |"
              for label, subset in _by_composition(pooled_rows, limit)],
            f"| median held-out gap shrink (n={pooled['n_gap_shrink']}) | >= 5x | "
            f"{fmt(pooled['gap_shrink_median'], 3)}x |",
            "", "| kind | datasets | exact (all) | above limit | exact above limit |",
            "|---|---|---|---|---|"]
        for kind, k in pooled["by_kind"].items():
            lines.append(f"| {kind} | {k['n_all']} | {_pct(k['exact_all'])} | "
                         f"{k['n_above']} | {_pct(k['exact_above'])} |")
        lines += ["", f"Regenerate: `replicate -m experiment=discrepancy_outside "
                  f"seed={','.join(str(r['seed']) for r in runs)} "
                  "figure=null manifest=null`, then `replicate-gather "
                  f"multirun/discrepancy_outside --output {SWEEP_CSV}`."]
    elif sweep:
        lines += ["", f"Documented sweep: not run yet (`{SWEEP_CSV}` missing)."]
    above = s["exact_rate_above_limit"]
    shrink = s["gap_shrink_median"]
    clean_ok = s["false_names_effect_free"] == 0 and s["false_unexplained_effect_free"] == 0
    rows = [
        SummaryRow(f"missing effects named exactly, outside data above the detection "
                   f"limit{scope}", "not in paper",
                   _goal(_pct_of(above, s["n_above_limit"]), above is not None and above >= 0.9),
                   ">= 90%", BEYOND),
        SummaryRow(f"false names / false 'unexplained' on effect-free outside data{scope}",
                   "not in paper",
                   _goal(f"{s['false_names_effect_free']} / "
                         f"{s['false_unexplained_effect_free']} of {s['n_effect_free']}",
                         clean_ok), "0 / 0", BEYOND),
        SummaryRow(f"median held-out gap shrink, outside data{scope}", "not in paper",
                   _goal(f"{fmt(shrink, 3)}x", shrink is not None and shrink >= 5), ">= 5x",
                   BEYOND),
        SummaryRow(f"valid outside trajectories refused{scope}", "not in paper",
                   _goal(str(s["refused"]), s["refused"] == 0), "0", BEYOND),
    ]
    if pooled:
        swept = pooled["exact_rate_above_limit"]
        clean = (pooled["false_names_effect_free"] == 0
                 and pooled["false_unexplained_effect_free"] == 0)
        rows += [
            SummaryRow(f"missing effects named exactly, documented sweep of "
                       f"{pooled['n_datasets']} more outside datasets, above the limit",
                       "not in paper",
                       _goal(_pct_of(swept, pooled["n_above_limit"]),
                             swept is not None and swept >= 0.9), ">= 90%", BEYOND),
            SummaryRow("false names / false 'unexplained', effect-free data of the sweep",
                       "not in paper",
                       _goal(f"{pooled['false_names_effect_free']} / "
                             f"{pooled['false_unexplained_effect_free']} of "
                             f"{pooled['n_effect_free']}", clean), "0 / 0", BEYOND)]
    return Section("\n".join(lines), rows)


def blind_section(result):
    """Correct-name rate, confusion matrix, false names, gap shrink, coefficient errors."""
    s = result["summary"]
    config = result["config"]["study"]
    lines = [
        "Not in the paper. In-house generator (`replication/discrepancy/generate.py`, which "
        "uses the suite's own simulator and the library's functional forms): a second row "
        "beside the outside data above. Each dataset hides one effect "
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
        f"| median coefficient error (correct names) | | "
        f"{_pct(s['coefficient_error_median'])} |",
        f"| coefficients within 10% (the issue's goal: every one) | 100% | "
        f"{_pct(s['coefficient_within_10pct'])} |",
        *([f"| truth within 2 standard errors of every fitted coefficient | | "
           f"{_pct(s['coefficient_within_2se'])} (largest error "
           f"{fmt(s['coefficient_z_max'], 3)} standard errors) |",
           f"| coefficients within 1 / 2 standard errors of the truth ("
           f"{_pct(EXACT_WITHIN['1'])} / {_pct(EXACT_WITHIN['2'])} were the errors exact "
           f"and normal; n={s['coefficient_z_within']['n']}) | | "
           f"{_pct(s['coefficient_z_within']['1'])} / {_pct(s['coefficient_z_within']['2'])} "
           f"(median {fmt(s['coefficient_z_median'], 2)} standard errors; "
           f"{fmt(EXACT_MEDIAN, 2)} if exact) |"]
          if s.get("coefficient_z_within") else []),
        f"| analysis time per dataset (median / max) | | "
        f"{fmt(s['wall_seconds_median'], 3)} s / {fmt(s['wall_seconds_max'], 3)} s |",
        "",
        "Confusion matrix (rows hidden, columns called; the right call for `gust`, outside "
        "the library, is `unexplained`):",
        "",
        "| hidden \\ called | " + " | ".join(s["calls"]) + " |",
        "|---|" + "---|" * len(s["calls"]),
    ]
    for hidden in s["hidden"]:
        counts = [str(s["confusion"][hidden][called]) for called in s["calls"]]
        lines.append(f"| {hidden} | " + " | ".join(counts) + " |")
    beyond = s.get("coefficient_beyond_10pct") or []
    if beyond:
        lines += ["", "Coefficients more than 10% from the truth, with the largest error over "
                  "their stated standard errors (the fit's cluster-robust covariance): "
                  + "; ".join(f"#{b['index']} {b['effect']} (noise {b['noise_h']:.2g} h): "
                              f"{_pct(b['error'])}"
                              + ("" if b["z_max"] is None
                                 else f", {fmt(b['z_max'], 3)} standard errors")
                              for b in beyond) + "."]
    lines += ["", f"![blind study]({result['figure']})" if result.get("figure") else ""]
    moderate = s["correct_rate_moderate_snr"]
    false_rate = s["false_name_rate_effect_free"]
    shrink = s["gap_shrink_median"]
    error = s["coefficient_error_median"]
    within = s["coefficient_within_10pct"]
    covered = [b["z_max"] for b in beyond]
    covered = (f"; the {len(covered)} beyond 10% are {fmt(max(covered), 3)} standard errors "
               "or less from the truth" if covered and None not in covered else "")
    rows = [
        SummaryRow("missing effect named, moderate SNR (in-house generator)", "not in paper",
                   _goal(_pct(moderate), moderate is not None and moderate >= 0.9), ">= 90%",
                   BEYOND),
        SummaryRow("false names on effect-free data (in-house generator)", "not in paper",
                   _goal(_pct(false_rate), false_rate is not None and false_rate <= 0.05),
                   "<= 5%", BEYOND),
        SummaryRow("median held-out gap shrink (in-house generator)", "not in paper",
                   _goal(f"{fmt(shrink, 3)}x", shrink is not None and shrink >= 5), ">= 5x",
                   BEYOND),
        SummaryRow("fitted coefficients within 10% of the truth (in-house generator)",
                   "not in paper",
                   _goal(f"{_pct(within)} of correct names (median error {_pct(error)})"
                         f"{covered}",
                         within is not None and within >= 1.0), "all within 10%", BEYOND),
    ]
    return Section("\n".join(lines), rows)


def example_section(result):
    """One hidden effect on 500 frames: where, what was named, the gap, the time."""
    hidden = result["hidden"]
    named = result["named_effects"]
    where = result["where"]
    gap = result["gap"]
    lines = [
        f"Hidden: `{hidden['effect']}` with noise {hidden['noise_h']:.3g} h on "
        f"{result['n_frames']} frames (spec in the manifest; the workflow "
        "sees positions only). Noise floor estimated from the data: "
        f"{fmt(where['noise_sigma_h'], 3)} h. Residual structure Q of the base model: "
        f"{fmt(where['Q'], 4)} (1 = noise); by direction: normal {fmt(where['Q_normal'], 3)}, "
        f"tangential {fmt(where['Q_tangential'], 3)}.",
        "",
        "| | named | parameters | held-out rollout RMS (h) | held-out one-step RMS (h) |",
        "|---|---|---|---|---|",
        f"| base model | | | {fmt(gap['before']['rollout'], 3)} | "
        f"{fmt(gap['before']['one_step'], 3)} |",
    ]
    for effect in named:
        # scalars and vectors; dicts (coefficients, their errors) and matrices (the
        # covariance, a mass map) are in the result, not in the table
        params = ", ".join(
            f"{k} = " + ("(" + ", ".join(fmt(x, 3) for x in v) + ")" if isinstance(v, list)
                         else fmt(v, 4))
            for k, v in effect["parameters"].items()
            if v is not None and not isinstance(v, dict)
            and not (isinstance(v, list) and any(isinstance(x, list) for x in v)))
        lines.append(f"| with effect | `{effect['name']}` | {params} | "
                     f"{fmt(gap['after']['rollout'], 3)} | {fmt(gap['after']['one_step'], 3)} |")
    truth = result.get("hidden_coefficients")
    if named and truth is not None and named[0]["name"] == hidden["effect"]:
        fitted = list(named[0]["parameters"]["coefficients"].values())
        lines += ["", "True coefficients " + ", ".join(fmt(t, 4) for t in truth)
                  + "; fitted " + ", ".join(fmt(f, 4) for f in fitted) + "."]
    lines += ["", f"Unexplained structure: {'yes' if result['unexplained'] else 'none'}. "
              f"Analysis time: {fmt(result['analysis_seconds'], 3)} s (goal <= 60 s).", ""]
    lines += [f"![where]({p})" for p in result.get("plots", [])]
    ok_time = result["analysis_seconds"] <= 60
    rows = [SummaryRow("500-frame dataset analysed", "not in paper",
                       _goal(f"{fmt(result['analysis_seconds'], 3)} s", ok_time), "<= 60 s",
                       BEYOND)]
    return Section("\n".join(lines), rows)


def calibration_section(result):
    """Null distributions of the decision statistics on effect-free data."""
    s = result["summary"]
    lines = [
        f"{s['n_datasets']} effect-free datasets (seeds separate from the blind study). "
        "Under the null the structure statistic Q is near 1 and no candidate's Wald "
        "statistic should exceed its Bonferroni chi2 threshold.",
        "",
        "| statistic | median | 90% | 95% | max |",
        "|---|---|---|---|---|",
        f"| Q | {fmt(s['Q_quantiles']['0.5'], 3)} | {fmt(s['Q_quantiles']['0.9'], 3)} | "
        f"{fmt(s['Q_quantiles']['0.95'], 3)} | {fmt(s['Q_max'], 3)} |",
        f"| max Wald / threshold | {fmt(s['wald_ratio_quantiles']['0.5'], 3)} | "
        f"{fmt(s['wald_ratio_quantiles']['0.9'], 3)} | "
        f"{fmt(s['wald_ratio_quantiles']['0.95'], 3)} | |",
        "",
        f"Q threshold in use: {fmt(s['q_threshold'], 3)}; Q above it: "
        f"{_pct(s['rate_Q_above_threshold'])}. Any candidate significant: "
        f"{_pct(s['rate_any_significant'])}; false names: {_pct(s['false_name_rate'])}; "
        f"false 'unexplained': {_pct(s['false_unexplained_rate'])}.",
    ]
    if (s["rate_any_significant"] or 0) > 0.05:
        lines += ["", "Were the Wald statistics exact, at most about 5% of these datasets "
                  "would have a candidate above its threshold; here "
                  f"{_pct(s['rate_any_significant'])} do (median "
                  f"{fmt(s['wald_ratio_quantiles']['0.5'], 3)} x the threshold): on effect-free "
                  "data the Wald test alone is far from calibrated, and the false-name rate "
                  "rests on the workflow's other checks before a name is kept (information "
                  "criterion, held-out rollout, the structure it removes), not on it."]
    ok = s["false_name_rate"] <= 0.05
    rows = [SummaryRow("false names, calibration set (in-house generator)", "not in paper",
                       _goal(_pct(s["false_name_rate"]), ok), "<= 5%", BEYOND)]
    return Section("\n".join(lines), rows)


def scale_section(result):
    """Workflow time against the number of frames (``bench_discrepancy_scale``)."""
    spec, m = result["spec"], result["metrics"]
    kinds = ", ".join(e["kind"] for e in spec["effects"]) or "none"
    lines = [
        f"One outside-generator dataset per length: K {fmt(spec['K'], 3)}, tau "
        f"{fmt(spec['tau'], 3)}, noise {fmt(spec['noise_h'], 2)} h, hidden {kinds}; the same "
        "draws at every length. Time: reading the file and the whole analysis.",
        "",
        "| frames | seconds | named | hidden (library names) | unexplained | gap before -> "
        "after (h) |",
        "|---|---|---|---|---|---|",
    ]
    lines += [f"| {r['frames']} | {fmt(r['seconds'], 3)} | {', '.join(r['named']) or 'none'} | "
              f"{', '.join(r['expected']) or 'none'} | {r['unexplained']} | "
              f"{fmt(r['gap_before'], 3)} -> {fmt(r['gap_after'], 3)} |"
              for r in result["rows"]]
    lines += ["", f"Growth exponent (log-log slope of the time against the frames): "
              f"{fmt(m['seconds_exponent_vs_frames'], 3)} (1: linear)."]
    if result.get("figure"):
        lines += ["", f"![discrepancy cost growth]({result['figure']})"]
    return Section("\n".join(lines))
