"""REPORT.md sections of the motion verdict studies
(:mod:`replication.experiments.motion_sensitivity`).

Each section prints the rate of every reading, the verdict over the readings and the
summary row of the claim it explains (``accuracy_section`` and ``study_section`` leave
those rows to these sections, so that each row names the reason measured here).
"""

from __future__ import annotations

from replication.experiments.sensitivity import verdict
from replication.report.build import Section, SummaryRow, anchor, fmt


def _value(value):
    """A config value as written in a Hydra override."""
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    return "null" if value is None else f"{value:g}" if isinstance(value, float) else str(value)


def _medians(row, method):
    """``centre px / omega %`` medians of one flow in one reading, and its failures."""
    m = row["methods"].get(method)
    if m is None:
        return "n/a"
    failed = f" ({m['n_failed']} failed)" if m.get("n_failed") else ""
    return f"{fmt(m['centre_px_median'], 3)} / {fmt(m['omega_pct_median'], 3)}{failed}"


def _reading(row):
    return ", ".join(f"`{key}={_value(value)}`" for key, value in row["overrides"].items())


def _table(result, columns):
    """Markdown table: one line per reading; ``columns`` [(header, function(row))]."""
    lines = ["| choice | value | " + " | ".join(h for h, _ in columns) + " |",
             "|---|---|" + "---|" * len(columns)]
    for row in result["readings"]:
        axis = result["axes"][row["axis"]]
        mark = " (the experiment's own)" if row["is_base"] else ""
        lines.append(f"| {axis['label']} | `{_value(row['value'])}`{mark} | "
                     + " | ".join(f(row) for _, f in columns) + " |")
    return lines


def _commands(result):
    name = result["experiment"]
    return (f"Regenerate with `replicate experiment={name} force=true` (each reading runs the "
            "base experiment's runner with the override shown; the figure is "
            f"`{result.get('figure', 'not drawn')}`).")


def flow_section(result):
    """Velocity fields (2.1): flow + rigid fit against the goal under every reading."""
    goal = result["goal_rate"]
    base = next(r for r in result["readings"] if r["is_base"])
    meeting, total = verdict(result, meets=lambda r: r["rate"] >= goal)
    best = max(result["readings"], key=lambda r: r["rate"])
    link = anchor(result["config"]["report"]["title"])
    noise = _value(result["config"]["noise_levels_255"])
    lines = [
        "The paper (2.1) sets velocity fields aside as \"too noisy\" to find rotations. "
        "`motion_accuracy` measures two of today's optical flows (scikit-image TV-L1 and iLK) "
        "followed by a robust rigid fit on the moving, eroded region; this study runs that "
        f"experiment's flow rows ({noise}/255 noise unless the noise is the choice) under "
        "each choice a reader of 2.1 could make differently: the flow's regularisation "
        "and warps, the motion threshold that defines the moving region, its erosion, and "
        f"the noise. A reading \"finds rotations\" when the better of the two flows is within "
        f"`motion_accuracy`'s goal (centre 1 px and omega 3 % without noise, 2 px and 5 % "
        f"with) on at least {goal:.0%} of the sequences. The noise of each run is drawn "
        "from the seed, the sequence's index and the noise level's index in the run's list, "
        f"so the {noise}/255 rows here draw other noise than `motion_accuracy`'s own list "
        "of levels: their medians differ from that section's by the sampling alone.",
        "",
        *_table(result, [
            ("best flow", lambda r: r["best_method"].replace(" flow + rigid fit", "")),
            ("within goal", lambda r: f"{r['rate']:.0%}"),
            *[(f"{m.replace(' flow + rigid fit', '')}: median centre px / omega %",
               lambda r, m=m: _medians(r, m))
              for m in ("TV-L1 flow + rigid fit", "iLK flow + rigid fit")],
        ]),
        "",
    ]
    base_text = (f"{base['best_method']} within the goal on {base['rate']:.0%} of the "
                 f"sequences with the experiment's settings")
    if meeting:
        which = "; ".join(f"{_reading(r)} ({r['rate']:.0%})" for r in meeting)
        text = (f"flows meet the goal on >= {goal:.0%} of the sequences under {len(meeting)} "
                f"of {total} readings: {which}; {base_text}")
        verdict_text = f"partly: the claim fails under {len(meeting)} of {total} readings"
        text += (f" (scored on the same {len(base['points'])} sequences they are picked "
                 "from: no held-out sequence tests them)")
    else:
        text = (f"under none of {total} readings do flows meet the goal on {goal:.0%} of the "
                f"sequences (best: {best['rate']:.0%} with {_reading(best) or 'the defaults'});"
                f" {base_text}")
        verdict_text = (f"partly: flows locate the centre within a few pixels (median), but "
                        f"under none of {total} readings meet the goal on {goal:.0%} of "
                        "the sequences")
    lines += [f"**Verdict:** {text}.", "",
              f"![velocity fields sensitivity]({result['figure']})" if result.get("figure")
              else "", "", _commands(result)]
    row = SummaryRow("velocity fields are too noisy to find rotations (2.1)",
                     "claimed, no numbers", text,
                     f"a flow within the accuracy goal on >= {goal:.0%} of sequences",
                     f"{verdict_text} ([sensitivity]({link}))")
    return Section("\n".join(lines), [row])


def segment_section(result):
    """Section 2.3 exactly as described: object-runs found under every reading."""
    goal = result["goal_rate"]
    base = next(r for r in result["readings"] if r["is_base"])
    meeting, total = verdict(result, meets=lambda r: r["rate"] >= goal)
    candidates = [r for r in result["readings"] if not result["axes"][r["axis"]]["beyond"]]
    best_rate = max(r["rate"] for r in candidates)
    tied = [r for r in candidates if r["rate"] == best_rate]
    link = anchor(result["config"]["report"]["title"])
    lines = [
        "`segment_study`'s `faithful` method is section 2.3 as the paper describes it (EA "
        "with sharing, one inflating radial snake, one restricted accumulation, none of the "
        "suite's additions). This study runs it under each choice the paper leaves open or "
        "states only as a range: population and generations (the paper: \"50 to 100\" "
        "generations with a typical population of 100; its Fig. 5: 150 individuals after 50), "
        "the sharing penalty, the size "
        "preference beta R/(R+r), the smallest disc, the gradient threshold, the snake's "
        "iterations (\"5 to 20\") and its tolerance, and one choice the paper states (the "
        "20% kept, varied for comparison). Rate: object-runs found "
        f"(`segment_study`'s criterion: IoU >= 0.7 and centre within 2 px) on the study "
        f"sequences; goal: {goal:.0%}, the pipeline's. Each reading runs "
        f"{result['config']['seeds']['faithful']} seeds per sequence; `segment_study` runs "
        "the same method with its own seed count, so its `faithful` rates differ from the "
        "reading marked as the experiment's own by the sampling alone.",
        "",
        *_table(result, [
            ("object-runs found", lambda r: f"{r['rate']:.0%}"),
            ("median IoU", lambda r: fmt(r["iou_median"], 2)),
            ("false regions/run", lambda r: fmt(r["false_regions_per_run"], 2)),
            ("runs", lambda r: str(r["runs"])),
        ]),
        "",
    ]
    if meeting:
        which = "; ".join(f"{_reading(r)} ({r['rate']:.0%})" for r in meeting)
        text = f"replicates under {len(meeting)} of {total} readings: {which}"
        verdict_text = f"replicated under {len(meeting)} of {total} readings"
    else:
        text = (f"finds {base['rate']:.0%} of object-runs as configured and at most "
                f"{best_rate:.0%} ("
                + ("; ".join(_reading(r) or "the defaults" for r in tied))
                + f") under any of {total} readings; goal {goal:.0%}")
        verdict_text = (f"not replicated: objects found, but under none of {total} readings "
                        f"{goal:.0%} of them")
    lines += [f"**Verdict:** 2.3 exactly as described {text}. Our diagnosis (in the "
              "segmentation section): a disc on a moving object must already be good to be "
              "kept, so it is rarely projected onto its IRC lines, and a snake that can only "
              "inflate keeps what its starting disc holds off the object. The readings above "
              "tune the same steps and leave both mechanisms in place; the suite's additions "
              "(`segment_study`'s ablations) are what remove them.", "",
              f"![segmentation sensitivity]({result['figure']})" if result.get("figure")
              else "", "", _commands(result)]
    row = SummaryRow("2.3 exactly as described (EA, inflating snake, one accumulation) "
                     "segments the rotating objects", "qualitative (Figs. 5-7)", text,
                     f">= {goal:.0%} of object-runs found (the pipeline's goal)",
                     f"{verdict_text} ([sensitivity]({link}))")
    return Section("\n".join(lines), [row])
