"""REPORT.md sections of the segmentation experiments (paper 2.3); numbers from results only."""

from __future__ import annotations

from replication.report.build import Section, SummaryRow, fmt

COST_NOTE = (
    "Disc cost: the paper's normalised IRC residual with the **absolute value** (a distance "
    "to each pixel's IRC line, an L1 fit less swayed by the pixels of other motions than a "
    "square), the paper's |grad I|^2 denominator times the 99th-percentile gradient (so it "
    "stays in pixels), each pixel's term capped, and the **mean** over the disc's pixels "
    "instead of the sum (the paper's beta R/(R+r) is then the only size preference, with r "
    "the radius of the disc's part inside the image, so that discs centred off the image "
    "cannot win it with a few pixels, as NicheGA's did before this was measured). Discs "
    "whose rotation explains their pixels no better than no motion at all are taken for the "
    "static background and dropped after the EA (not in the paper: the 1/omega "
    "normalisation lets small static discs fit a fast rotation about their own centre)."
)


ASSIGN_NOTE = (
    "Per-pixel assignment (not in the paper; `method.assign`): once every object's rotation "
    "is known, each pixel with a gradient is given to the motion among {static, object 1..k} "
    "whose normal-flow residuals, averaged over a Gaussian neighbourhood with |grad I|^2 "
    "weights, are lowest by a margin; patches without a gradient, then undecided ones, join "
    "the object whose labels ring them, enclosed holes are filled unless confidently "
    "static, and each object's "
    "rotation is accumulated again over its new mask. Objects of one motion are merged "
    "first, and an object left with too little of its snake region is dropped and the rest "
    "assigned again. Regions that no motion found explains (every smoothed residual high) "
    "get the single-rotation accumulation of 2.2 over their own pixels and become objects "
    "(`assign.rescue`): a radial snake is star-shaped around its centre and cannot follow a "
    "C-shape whose rotation centre lies in its own hole, nor leave out the flat faces of a "
    "brick texture, and the EA sometimes misses an object altogether."
)


def _assign_text(method):
    """The assignment note when the config switches it on, else ''."""
    assign = (method or {}).get("assign") or {}
    return "\n\n" + ASSIGN_NOTE if assign.get("enabled") else ""


def data_section(result):
    """The generated sequences: objects, speeds, areas."""
    lines = ["| sequence | role | objects (xi, eta, omega; area px) | background |",
             "|---|---|---|---|"]
    for name, item in result["sequences"].items():
        objects = "; ".join(f"({o['xi']:g}, {o['eta']:g}, {o['omega']:+g}; {a})"
                            for o, a in zip(item["objects"], item["areas_px"]))
        lines.append(f"| {name} | {item['role']} | {objects} | "
                     f"{item['background_texture']} |")
    text = ("256 x 256 sequences of 2 frames, 1/255 camera noise, 8-bit; each object turns "
            "about its own centre on a static textured background. Files and sha256 in "
            f"`{result['data_dir']}/manifest.json`.\n\n" + "\n".join(lines))
    return Section(text)


def segment_section(result):
    """One sequence: the objects found, Figs. 5-7."""
    lines = ["| object | xi | eta | omega | area (px) |", "|---|---|---|---|---|"]
    for k, item in enumerate(result["objects"], 1):
        lines.append(f"| {k} | {fmt(item['xi'])} | {fmt(item['eta'])} | "
                     f"{fmt(item['omega'])} | {item['area']} |")
    text = [f"Sequence `{result['data']}`; {len(result['objects'])} object(s) found in "
            f"{result['pipeline_seconds']:.1f} s ({result['evaluations']} disc evaluations); "
            f"{sum(result['rotating'])} of {len(result['rotating'])} retained discs rotating.",
            "", "\n".join(lines), ""]
    rows = []
    score = result.get("score")
    if score:
        text.append("Against the truth: " + "; ".join(
            f"label {o['label']}: IoU {o['iou']:.2f}, centre error {fmt(o['centre_px'], 3)} px, "
            f"omega error {fmt(o['omega_pct'], 3)} %" for o in score["per_object"])
            + f"; {score['false_regions']} false region(s), {score['split_regions']} "
            "split region(s).")
    for path in result.get("figures", []):
        text.append(f"\n![{path}]({path})")
    text.append("\n" + COST_NOTE + _assign_text((result.get("config") or {}).get("method")))
    return Section("\n".join(text), rows)


def _table(summary):
    """Markdown rows of a study summary (one line per method)."""
    lines = ["| method | runs | found (centre <= 2 px, IoU >= 0.7) | objects found in >= 90% "
             "of runs | worst object | objects/run | median centre err (px) | median omega "
             "err (%) | median IoU | false regions/run | split regions/run | false regions/run, "
             "static | median s/run |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in summary:
        lines.append(
            f"| {s['method']} | {s['runs']} | {s['found_fraction']:.2f} | "
            f"{s['objects_at_90pct']}/{s['objects']} | {s['worst_object_rate']:.2f} | "
            f"{s['found_objects_per_run']:.2f} | {fmt(s['centre_px_median'], 3)} | "
            f"{fmt(s['omega_pct_median'], 3)} | {s['iou_median']:.2f} | "
            f"{s['false_regions_per_run']:.2f} | {s['split_regions_per_run']:.2f} | "
            f"{fmt(s['static_false_regions_per_run'], 3)} | "
            f"{s['seconds_median']:.1f} |")
    return lines


def study_section(result):
    """Study over seeds and sequences, with the summary rows for the goals."""
    goals = result["goals"]
    method = result["config"]["method"]
    lines = _table(result["summary"])
    rows = []
    for s in result["summary"]:
        # the row of 2.3 exactly as described (the faithful method) is written by
        # segment_sensitivity's section (replication/report/motion_sensitivity.py)
        if s["method"] == "pipeline":
            met = s["objects_at_90pct"] == s["objects"]
            steps = ("EA, snakes, restricted accumulation and per-pixel assignment"
                     if (method.get("assign") or {}).get("enabled") else
                     "EA, snakes and restricted accumulation")
            rows.append(SummaryRow(
                f"2.3 with this suite's additions: {steps} find every rotating object",
                "qualitative (Figs. 5-7)",
                f"{s['found_fraction']:.0%} of object-runs found; {s['objects_at_90pct']}/"
                f"{s['objects']} objects in >= 90% of runs; median IoU {s['iou_median']:.2f}",
                f"every object in >= {goals['found_rate_at_least']:.0%} of runs, centre <= "
                f"{goals['centre_px_at_most']:g} px, IoU >= {goals['iou_at_least']:g}",
                "beyond the paper (its method with the suite's additions)" if met
                else "not met"))
    per = ["", "Per object, fraction of runs found (pipeline):", ""]
    for s in result["summary"]:
        if s["method"] == "pipeline":
            per += [f"- {key}: {rate:.2f}" for key, rate in s["per_object_rate"].items()]
    additions = (f"`pipeline` is the configured method: the paper's EA (population "
                 f"{method['ea']['pop_size']}, {method['ea']['generations']} generations, keep "
                 f"{method['ea']['keep']:g}) with these additions: fresh individuals projected "
                 f"once = {method['ea'].get('project_fresh')}, snake sectors may deflate = "
                 f"{method['snake'].get('deflate')}, snake/accumulation rounds = "
                 f"{method['snake'].get('rounds')}, extra snake seeds per object = "
                 f"{method['merge'].get('extra_seeds', 0)}, irc.refine = "
                 f"{method['accumulation'].get('refine', False)}, per-pixel assignment = "
                 f"{(method.get('assign') or {}).get('enabled', False)} (rescued regions: up "
                 f"to {(method.get('assign') or {}).get('rescue', 0)}). `faithful` is the same "
                 "with "
                 "every addition off (the paper's order: EA, one snake, one accumulation), but "
                 "with the cost choices and the static-disc filter described below, which "
                 "any implementation of the paper's formula needs in some form; "
                 "`refined` is the pipeline followed by `irc.refine` (the single-rotation "
                 "module's warping refinement) of each object's rotation. "
                 "`nichega` replaces the EA by pymoo's NicheGA on the same cost and budget "
                 "(the rest of the pipeline, additions included, unchanged); "
                 "`flow` is TV-L1 optical flow then sequential RANSAC of rigid motions. "
                 "A false region lies mostly on the static background; a split region "
                 "mostly on a true object that another region found matches better (the "
                 "object found in pieces, or twice).")
    by_name = {s["method"]: s for s in result["summary"]}
    notes = []
    if "pipeline" in by_name and "faithful" in by_name:
        notes.append(
            f"The faithful scheme finds {by_name['faithful']['found_fraction']:.0%} of "
            f"object-runs against {by_name['pipeline']['found_fraction']:.0%} with the "
            "additions. Our diagnosis (from runs of the EA alone): an individual is kept only "
            "if already good, so a disc on a moving object rarely survives "
            "long enough to be projected onto its IRC lines, while small static discs do; and "
            "a radial snake that can only inflate keeps the parts of its starting disc that "
            "lie off the object. The paper reports no numbers to compare with (Figs. 5-7 are "
            "qualitative).")
    if "pipeline" in by_name:
        p = by_name["pipeline"]
        larger = _share_overestimated(result, "pipeline")
        notes.append(
            f"The median centre error is {fmt(p['centre_px_median'], 3)} px (the true centres "
            "lie on the 1-pixel accumulator grid, so 0 means the right cell). "
            + _misses_text(result, "pipeline", "study", goals)
            + " The accumulation's omega is biased "
            f"(median |error| {fmt(p['omega_pct_median'], 3)} %; |omega| too large in "
            f"{larger:.0%} of the detected object-runs), as the peak of 2.2 is.")
        if "no_assign" in by_name:
            notes.append(_snake_misses_text(result, "no_assign"))
    ablations = result.get("ablations") or {}
    if ablations and "pipeline" in by_name:
        runs = max(result["seeds"].get(name, 0) for name in ablations)
        same = [o["found"] for r in result["rows"] if r["method"] == "pipeline"
                and r["role"] == "study" and r["run"] < runs for o in r["per_object"]]
        parts = [f"`{name}` ({_overrides_text(change)}): "
                 f"{by_name[name]['found_fraction']:.0%}" for name, change in ablations.items()
                 if name in by_name]
        rate = sum(same) / max(len(same), 1)
        level = [f"`{name}`" for name in ablations
                 if name in by_name and by_name[name]["found_fraction"] >= rate]
        notes.append(
            f"Ablations, each the pipeline with one addition off, on the first {runs} runs of "
            f"each sequence (where the pipeline finds {rate:.0%} of object-runs): "
            + "; ".join(parts) + "."
            + (f" The ablations {', '.join(level)} lose nothing on these runs ({runs} "
               "per sequence, too few to rank the additions more finely)."
               if level else ""))
    if "refined" in by_name:
        q = by_name["refined"]
        notes.append(
            f"With the warping refinement of the single-rotation module after the restricted "
            f"accumulation (`refined`), the median omega error falls to "
            f"{fmt(q['omega_pct_median'], 3)} % and the median centre error is "
            f"{fmt(q['centre_px_median'], 3)} px, for {q['seconds_median']:.1f} s per run.")
    heldout = result.get("summary_heldout") or []
    if heldout:
        names = [n for n, item in result["sequences"].items() if item["role"] == "heldout"]
        per += ["", f"**Held-out sequences** ({', '.join(names)}; no setting was tuned on "
                "them: every setting was chosen on the study sequences above. They are not "
                "strictly blind, though: their results were seen while the assignment step "
                "was developed, and two later changes to it (a looser rule for the parts "
                "that overlap a region, and filling flat patches first) were made after "
                "that, prompted by a unit test and by the study's brick C):", ""]
        per += _table(heldout)
        per += ["", _misses_text(result, "pipeline", "heldout", goals)]
        for s in heldout:
            if s["method"] == "pipeline":
                rows.append(SummaryRow(
                    "2.3 with this suite's additions, on held-out sequences (nothing tuned "
                    "on them; not strictly blind, see the section)",
                    "qualitative (Figs. 5-7)",
                    f"{s['found_fraction']:.0%} of object-runs found; {s['objects_at_90pct']}/"
                    f"{s['objects']} objects in >= 90% of runs; median IoU "
                    f"{s['iou_median']:.2f}",
                    f"every object in >= {goals['found_rate_at_least']:.0%} of runs",
                    "beyond the paper (its method with the suite's additions)"
                    if s["objects_at_90pct"] == s["objects"] else "not met"))
    text = (additions + "\n\n" + "Seeds per method: "
            + ", ".join(f"{m} {n}" for m, n in result["seeds"].items())
            + "; a run is found for a true object when its best-overlapping region has IoU >= "
            "0.7 with the frame-0 label mask and its centre is within 2 px. Centre and omega "
            "errors are medians over the objects with any overlapping region.\n\n"
            + "\n".join(lines) + "\n" + "\n".join(per) + "\n\n" + "\n\n".join(notes)
            + "\n\n" + COST_NOTE + _assign_text(method))
    return Section(text, rows)


def _miss_counts(result, method, role):
    """Per true object of ``method`` on ``role`` sequences: runs, found, and misses by
    cause (no overlapping region; IoU too low; centre too far)."""
    goals = result["goals"]
    counts = {}
    for r in result["rows"]:
        if r["method"] != method or r["role"] != role:
            continue
        for o in r["per_object"]:
            c = counts.setdefault(f"{r['sequence']}:{o['label']}",
                                  {"runs": 0, "found": 0, "none": 0, "iou": 0, "centre": 0})
            c["runs"] += 1
            if o["found"]:
                c["found"] += 1
            elif o["iou"] == 0 or o["centre_px"] is None:
                c["none"] += 1
            elif o["iou"] < goals["iou_at_least"]:
                c["iou"] += 1
            else:
                c["centre"] += 1
    return counts


def _misses_text(result, method, role, goals):
    """Which objects miss the goal and how, computed from the rows."""
    counts = _miss_counts(result, method, role)
    short = {k: c for k, c in counts.items()
             if c["found"] < goals["found_rate_at_least"] * c["runs"]}
    where = "study" if role == "study" else "held-out"
    if not short:
        worst = min(counts, key=lambda k: counts[k]["found"] / counts[k]["runs"])
        c = counts[worst]
        fewest = (f" (the fewest: {worst}, {c['found']}/{c['runs']})"
                  if c["found"] < c["runs"] else "")
        return (f"On the {where} sequences every object is found in at least "
                f"{goals['found_rate_at_least']:.0%} of the `{method}` runs{fewest}.")
    parts = [f"{k} (found in {c['found']}/{c['runs']} runs; missed: no overlapping region "
             f"in {c['none']}, IoU < {goals['iou_at_least']:g} in {c['iou']}, centre > "
             f"{goals['centre_px_at_most']:g} px in {c['centre']})" for k, c in short.items()]
    return (f"On the {where} sequences the goal is not met for " + "; ".join(parts) + ".")


def _snake_misses_text(result, method):
    """Without the assignment: how the snake masks miss (from ``method``'s study rows)."""
    counts = _miss_counts(result, method, "study")
    total = {key: sum(c[key] for c in counts.values()) for key in ("runs", "none", "iou",
                                                                   "centre")}
    return (f"Without the per-pixel assignment (`{method}`) the object-runs missed are "
            f"{total['iou']} by IoU, {total['centre']} by centre and {total['none']} without "
            f"any overlapping region, of {total['runs']}. In our diagnostic runs the snake's "
            "masks, star-shaped around their disc's centre, took in the hole of a C-shape "
            "whose rotation centre lies in that hole and left out the flat faces of the "
            "brick texture, which have no gradient to grow over; the objects with no "
            "overlapping region are those the EA missed altogether.")


def _overrides_text(change):
    """``{"ea": {"keep": 0.1}}`` as ``ea.keep=0.1``."""
    return ", ".join(f"{group}.{key}={value}" for group, values in change.items()
                     for key, value in values.items())


def _share_overestimated(result, method):
    """Fraction of detected object-runs of ``method`` whose |omega| exceeds the truth's."""
    truth = {name: {o["label"]: o["omega"] for o in item["objects"]}
             for name, item in result["sequences"].items()}
    signs = [o["omega_pct"] * truth[r["sequence"]][o["label"]] > 0
             for r in result["rows"] if r["method"] == method and r["role"] == "study"
             for o in r["per_object"] if o["iou"] > 0 and isinstance(o["omega_pct"], float)]
    return sum(signs) / len(signs) if signs else float("nan")


def bench_section(result):
    """Pipeline wall time against the 10 s goal."""
    m = result["metrics"]
    goal = result["goals"]["pipeline_s_at_most"]
    text = "\n".join(["| metric | value |", "|---|---|"]
                     + [f"| {key} | {fmt(value)} |" for key, value in m.items()])
    row = SummaryRow("one whole segmentation run is fast", "n/a (1995 hardware not comparable)",
                     f"{m['pipeline_s_median']:.2f} s median ({m['numba_threads']} threads)",
                     f"<= {goal:g} s", "beyond the paper" if m["pipeline_s_median"] <= goal
                     else "not replicated")
    return Section(f"Data `{result['data']}`.\n\n" + text, [row])


def objects_section(result):
    """Segmentation time against the number of objects (``bench_segment_objects``)."""
    side = result["frame_side"]
    lines = [f"`bench_segment`'s pipeline on {side} x {side} sequences with k textured discs "
             "(a 3 x 3 grid, the first k cells), median of "
             f"{result['config']['repeats']} runs after a warm-up; found: `segment_study`'s "
             "criterion (IoU >= 0.7, centre within 2 px).", "",
             "| objects | median s | found |", "|---|---|---|"]
    lines += [f"| {r['objects']} | {fmt(r['seconds_median'], 3)} | {r['found_fraction']:.0%} |"
              for r in result["rows"]]
    lines += ["", "Growth exponent (log-log slope of the time against the objects): "
              f"{fmt(result['metrics']['seconds_exponent_vs_objects'], 3)} (1: linear)."]
    if result.get("figure"):
        lines += ["", f"![segmentation cost growth]({result['figure']})"]
    return Section("\n".join(lines))
