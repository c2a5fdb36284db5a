"""Regenerate every measured figure and number of the documentation's study page.

    python scripts/make_docs.py            # the study on the default curl, its sensitivity
                                           # to the SE stiffness, the default checks and the
                                           # studies on the squat jump and the drop
                                           # landing (~45 min on 2 cores)
    python scripts/make_docs.py --check    # only check that every page holds its generated
                                           # blocks (scripts/docblocks.py), that the cheap
                                           # ones (techniques, presets' motions) are current
                                           # and that the optima of docs/optimise.md regenerate
                                           # within their stated spread (~1 min)
    python scripts/make_docs.py --jump     # only the study on the squat jump (~25 min)
    python scripts/make_docs.py --landing  # only the study on the drop landing and its
                                           # touchdown speeds (~2 min)
    python scripts/make_docs.py --curl     # the curl's study and sensitivity, not the jump
                                           # nor the landing
    python scripts/make_docs.py --presets  # only the presets' motions (docs/presets.md), their
                                           # conventions figures and the result figures of
                                           # the bodies on the ground

Runs ``torquesim compare`` on the default curl into a temporary folder, copies its figures to
``docs/figures/`` and rewrites the blocks of ``docs/study.md`` between
``<!-- generated: NAME -->`` and ``<!-- end generated -->`` from its verdict.csv, results.csv
and manifest.json (and the default checks' study, ``scripts/accuracy_checks.py``'s grid).
Nothing in those blocks is typed by hand; the date, machine and load average of the run are
written beside the numbers.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
import tempfile
from datetime import UTC, datetime
from pathlib import Path

from docblocks import (  # noqa: E402  (scripts/)
    MOTION_PRESETS,
    ROOT,
    contact_blocks,
    current_block,
    fields_block,
    missing_blocks,
    preset_motion_blocks,
    techniques_block,
    write_blocks,
)

FIGURES = ("convergence.png", "work_precision.png", "time_constants.png")
#: The studies on the squat jump and the drop landing: their steps (the durations 0.55 s and
#: 0.3 s are multiples of each) and the figures kept, renamed with a ``jump_`` or
#: ``landing_`` prefix (`GROUND_STUDIES`).
GROUND_STEPS = ("--steps", "5,2.5,1,0.5,0.25,0.1,0.05,0.025")
GROUND_FIGURES = ("work_precision.png", "time_constants.png")
#: The sensitivity figure: ``compare --vary`` of the SE stiffness.
SENSITIVITY = ("--vary", "se_stiffness=200,600,3000")
#: The landing's study again at these touchdown speeds (m/s; drops of 0.1, 0.3 and 0.59 m).
LANDING_SPEEDS = ("--vary", "landing_speed=1.4,2.43,3.4")


def _rows(path: Path) -> list[dict]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def _ms(text: str) -> str:
    return f"{float(text):.3g}" if text else "—"


def verdict_block(folder: Path, manifest: dict) -> str:
    lines = ["| accuracy | cheapest (step) | modelled cost (ms) | runner-up (step) | "
             "cost ratio | measured wall-time ratio (range over repeats) |",
             "|---|---|---|---|---|---|"]
    for v in _rows(folder / "verdict.csv"):
        tie = " (tie)" if v["tie"] == "True" else ""
        wall = (f"{float(v['wall_time_ratio']):.2g} ({float(v['wall_time_ratio_low']):.2g}–"
                f"{float(v['wall_time_ratio_high']):.2g})" if v["wall_time_ratio"] else "—")
        lines.append(f"| {float(v['target_deg']):g}° | {v['cheapest']} "
                     f"({v['cheapest_setting'] or '—'}){tie} | {_ms(v['modelled_cost_ms'])} | "
                     f"{v['runner_up'] or '—'} ({v['runner_up_setting'] or '—'}) | "
                     f"{float(v['cost_ratio']):.2f} | {wall} |"
                     if v["runner_up"] else
                     f"| {float(v['target_deg']):g}° | {v['cheapest']} "
                     f"({v['cheapest_setting'] or '—'}) | {_ms(v['modelled_cost_ms'])} | — | — "
                     "| — |")
    calibration = manifest["calibration_s"]
    names = {"fixed.step.monolithic": "monolithic loop, per step",
             "fixed.step.partitioned": "partitioned loop, per step (exchange)",
             "fixed.body": "one body evaluation", "fixed.muscle": "one muscle evaluation",
             "fixed.newton": "one Newton iteration (IMEX)",
             "fixed.jacobian": "one linearisation and factorisation of the body's stiff "
             "forces (imex-ros2)"}
    unit_times = ", ".join(
        f"{text} {calibration[key] * 1e9:.3g} ns" if calibration[key] > 0 else
        f"{text} not resolved (absorbed by the others)"
        for key, text in names.items() if key in calibration)
    load = manifest.get("load_average_1min")
    return "\n".join([
        *lines, "",
        f"Measured with `torquesim compare` on {manifest['created'][:10]}, "
        f"{manifest['machine'].get('cpus', '?')} cores, load average "
        f"{'unknown' if load is None else f'{load:.2f}'} at the end of the run "
        f"(torquesim {manifest['torquesim_version']}). Unit times calibrated in that run: "
        f"{unit_times}.", ""])


def limits_block(folder: Path, manifest: dict, case: str = "curl") -> str:
    from torquesim.study.compare import observed_order
    from torquesim.study.report import _limit_text

    rows = []
    for r in _rows(folder / "results.csv"):
        r = dict(r)
        r["h_s"] = float(r["h_s"]) if r["h_s"] else None
        r["max_error_rad"] = float(r["max_error_rad"])
        r["stable"] = r["stable"] == "True"
        r["guard_exceeded"] = r["guard_exceeded"] == "True"
        rows.append(r)
    smooth = manifest.get("smooth_case_orders", {})
    lines = [f"| technique | stability limit | observed order ({case}) | "
             "order on the smooth case |",
             "|---|---|---|---|"]
    for name in dict.fromkeys(r["technique"] for r in rows):
        if not any(r["technique"] == name and r["h_s"] for r in rows):
            continue
        order = observed_order(rows, name)
        s = smooth.get(name)
        lines.append(f"| {name} | {_limit_text(rows, name)} | "
                     f"{'none (no asymptotic range)' if order is None else f'{order:.2f}'} | "
                     f"{'—' if s is None else f'{s:.2f}'} |")
    return "\n".join([*lines, ""])


def checks_block() -> str:
    import torquesim as ts
    from torquesim.study.checks import RIGHT_RAD, WRONG_RAD, check_study

    counts = {"wrong": 0, "missed": 0, "right": 0, "alarms": 0, "runs": 0}
    for preset in ("builtin:elbow-curl", "builtin:arm-raise"):
        for r in check_study(ts.load_model(preset)):
            counts["runs"] += 1
            counts["wrong"] += r["max_error_rad"] > WRONG_RAD
            counts["missed"] += r["outcome"] == "missed"
            counts["right"] += r["max_error_rad"] <= RIGHT_RAD
            counts["alarms"] += r["outcome"] == "false alarm"
    return (f"Of {counts['runs']} runs (the curl and the arm raise; monolithic, IMEX, "
            "imex-ros2 and all 24 coupling variants; steps 20, 10, 5, 2, 1, 0.5 and 0.25 ms) "
            "with `simulate()`'s "
            f"default arguments, {counts['wrong']} end more than {WRONG_RAD:g} rad off the "
            f"reference and {counts['missed']} of them are silent; of the {counts['right']} "
            f"within {RIGHT_RAD:g} rad, {counts['alarms']} carry a warning (measured "
            f"{datetime.now(UTC).date()}, `python scripts/accuracy_checks.py` lists them).\n")


def stiffness_block(preset: str, what: str) -> str:
    """Which part of a body on the ground is stiff: the smallest time constant of its units
    and of its ground contacts over a monolithic run at 25 µs, and the RK4 step limit each
    sets. ``what`` names the motion in the text ("the jump")."""
    import torquesim as ts
    from torquesim.solvers.fixed_step import RK4_STABILITY_LIMIT

    run = ts.simulate(ts.load_model(f"builtin:{preset}"), "monolithic", 2.5e-5)
    unit, contact = (run.settings[f"{k}_time_constant_min_s"] for k in ("unit", "contact"))
    return (f"Over {what} (monolithic RK4, 25 µs) the units' smallest time constant is "
            f"{unit * 1e3:.3g} ms (RK4 stable for h ≤ {RK4_STABILITY_LIMIT * unit * 1e3:.3g} "
            f"ms) and the ground contacts' {contact * 1e3:.3g} ms (h ≤ "
            f"{RK4_STABILITY_LIMIT * contact * 1e3:.3g} ms): the muscle part is still the stiff "
            "one, by a factor of "
            f"{contact / unit:.0f}, but the contacts now cap the step of IMEX too, whose body "
            "part (contacts included) stays explicit; imex-ros2 treats the contacts "
            f"implicitly (measured {datetime.now(UTC).date()}).\n")


#: The studies on a body on the ground: preset → (block and figure prefix, the motion in
#: words). Their steps (`GROUND_STEPS`) divide each preset's duration.
GROUND_STUDIES = {"squat-jump": ("jump", "the jump"),
                  "drop-landing": ("landing", "the landing")}


def speeds_block(folder: Path) -> str:
    """The landing's study at each touchdown speed (`LANDING_SPEEDS`): IMEX's and
    imex-ros2's stability limits, the cheapest technique at each accuracy and the cost
    ratio of IMEX to imex-ros2 at 0.1°."""
    rows = _rows(folder / "sensitivity.csv")
    targets = ("1", "0.1", "0.01", "0.001")
    lines = ["| touchdown speed | stability limit: imex / imex-ros2 | "
             + " | ".join(f"cheapest at {t}°" for t in targets)
             + " | modelled cost at 0.1°, imex / imex-ros2 |",
             "|---|---|" + "---|" * len(targets) + "---|"]
    for value in dict.fromkeys(r["value"] for r in rows):
        by = {r["technique"]: r for r in rows if r["value"] == value}
        imex, ros2 = by["imex"], by["imex-ros2"]

        def limit(r):
            return f"{float(r['stability_limit_s']) * 1e3:g} ms" if r["stability_limit_s"] \
                else "none"

        ratio = (f"{float(imex['cost_0.1deg_s']) / float(ros2['cost_0.1deg_s']):.2f}"
                 if imex["cost_0.1deg_s"] and ros2["cost_0.1deg_s"] else "—")
        lines.append(f"| {float(value):g} m/s | {limit(imex)} / {limit(ros2)} | "
                     + " | ".join(imex[f"cheapest_{t}deg"] or "none" for t in targets)
                     + f" | {ratio} |")
    return ("`torquesim compare --model builtin:drop-landing " + " ".join(LANDING_SPEEDS)
            + "` (the stability limit: the largest step within 1° of the reference; measured "
            f"{datetime.now(UTC).date()}):\n\n" + "\n".join(lines) + "\n")


def ground_blocks(torquesim, tmp: Path, preset: str) -> dict[str, str]:
    """The study on a body on the ground (`GROUND_STUDIES`): its verdict, limits and
    stiffness blocks; copies its figures to docs/figures/<prefix>_*.png."""
    prefix, what = GROUND_STUDIES[preset]
    folder = tmp / prefix
    code = torquesim(["compare", "--model", f"builtin:{preset}", *GROUND_STEPS, "--out",
                      str(folder), "--quiet"])
    if code:
        sys.exit(f"torquesim compare on builtin:{preset} failed (exit {code})")
    manifest = json.loads((folder / "manifest.json").read_text())
    for name in GROUND_FIGURES:
        shutil.copyfile(folder / name, ROOT / "docs" / "figures" / f"{prefix}_{name}")
    blocks = {f"{prefix}-verdict": verdict_block(folder, manifest),
              f"{prefix}-limits": limits_block(folder, manifest, prefix),
              f"{prefix}-stiffness": stiffness_block(preset, what)}
    if preset == "drop-landing":
        speeds = tmp / f"{prefix}-speeds"
        code = torquesim(["compare", "--model", f"builtin:{preset}", *LANDING_SPEEDS,
                          *GROUND_STEPS, "--out", str(speeds), "--quiet"])
        if code:
            sys.exit(f"torquesim compare --vary on builtin:{preset} failed (exit {code})")
        blocks["landing-speeds"] = speeds_block(speeds)
    return blocks


#: Slack around the stated spread of an optimum, relative (the spread is measured with the
#: kernel sets of one CPU; another CPU's own may land just outside).
SPREAD_SLACK = 2e-3


def check_optimise_spread() -> list[str]:
    """Regenerate the curl's and the plain jump's optimum of docs/optimise.md (seed 1, on this
    machine) and hold each to the spread across OpenBLAS kernel sets that
    docs/data/optimise_spread.json states (`benchmarks/bench_optimise.py` part 4)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_optimise import SPREAD_CASES, SPREAD_FILE, optimum_in_process

    stated = json.loads(SPREAD_FILE.read_text())
    problems = []
    for case, (_, _, goal, scale) in SPREAD_CASES.items():
        low, high = stated[case]["low"], stated[case]["high"]
        value = optimum_in_process(case)
        slack = SPREAD_SLACK * max(abs(low), abs(high))
        if value is None or not low - slack <= value <= high + slack:
            problems.append(f"docs/optimise.md: the {case} optimum ({goal}) regenerated here is "
                            f"{'a failed run' if value is None else f'{value * scale:.2f}'}, "
                            f"outside the stated {low * scale:.2f}–{high * scale:.2f}; run "
                            "python benchmarks/bench_optimise.py --write-docs")
        else:
            print(f"{case}: optimum {value * scale:.2f} within the stated "
                  f"{low * scale:.2f}–{high * scale:.2f}")
    return problems


def conventions_figures() -> None:
    """docs/figures/conventions_<preset>.png: each preset's angle conventions, as
    ``torquesim model NAME --conventions`` draws them."""
    import torquesim as ts
    from torquesim.cli import conventions_figure
    from torquesim.plots import save_figure

    for name in MOTION_PRESETS:
        path = ROOT / "docs" / "figures" / f"conventions_{name.replace('-', '_')}.png"
        save_figure(conventions_figure(ts.load_model(f"builtin:{name}")), path)
        print(f"wrote {path.relative_to(ROOT)}")


#: The bodies on the ground drawn as `simulate --plot` draws them, each with the technique
#: and step its page names: the tutorial's IMEX at 0.25 ms for the jumps, imex-ros2 for the
#: landing (its impact holds IMEX below 0.1 ms; docs/study.md).
RESULT_FIGURES_OF = {"squat-jump": "imex", "countermovement-jump": "imex",
                     "drop-landing": "imex-ros2"}


def result_figures() -> None:
    """docs/figures/result_<name>.png: each of `RESULT_FIGURES_OF` as ``torquesim simulate
    --model builtin:NAME --method METHOD --step 0.25ms --plot`` draws it (strobe, forces,
    centre of mass, joints)."""
    import torquesim as ts
    from torquesim.plots import plot_result, save_figure

    for name, method in RESULT_FIGURES_OF.items():
        run = ts.simulate(ts.load_model(f"builtin:{name}"), method, 0.25e-3)
        path = ROOT / "docs" / "figures" / f"result_{name.replace('-', '_')}.png"
        save_figure(plot_result(run), path)
        print(f"wrote {path.relative_to(ROOT)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="only check that every docs page has its generated blocks (and "
                             "that the techniques table is the registry's)")
    parser.add_argument("--techniques", action="store_true",
                        help="only rewrite the techniques table of docs/concepts.md and the "
                             "fields table of docs/model-files.md")
    parser.add_argument("--jump", action="store_true",
                        help="only the study on the squat jump")
    parser.add_argument("--landing", action="store_true",
                        help="only the study on the drop landing")
    parser.add_argument("--curl", action="store_true",
                        help="the curl's study, its sensitivity and the default checks, not "
                             "the jump nor the landing")
    parser.add_argument("--presets", action="store_true",
                        help="only the presets' motions of docs/presets.md, their conventions "
                             "figures and the result figures of the bodies on the ground")
    args = parser.parse_args()
    problems = missing_blocks()
    if problems:
        sys.exit("\n".join(problems))
    if current_block("docs/concepts.md", "techniques") != techniques_block():
        if args.check:
            sys.exit("docs/concepts.md: the techniques table differs from the registry; run "
                     "python scripts/make_docs.py --techniques")
        write_blocks("docs/concepts.md", {"techniques": techniques_block()})
    if current_block("docs/model-files.md", "model-fields") != fields_block():
        if args.check:
            sys.exit("docs/model-files.md: the fields table differs from the model's tables; "
                     "run python scripts/make_docs.py --techniques")
        write_blocks("docs/model-files.md", {"model-fields": fields_block()})
    if args.techniques:
        return
    motions = preset_motion_blocks()
    stale = [name for name, body in motions.items()
             if current_block("docs/presets.md", name) != body]
    if stale and args.check:
        sys.exit(f"docs/presets.md: {', '.join(stale)} differ from the presets' motions; run "
                 "python scripts/make_docs.py --presets")
    if stale:
        write_blocks("docs/presets.md", {name: motions[name] for name in stale})
    contacts = contact_blocks()
    if current_block("docs/model.md", "contacts-squat-jump") != contacts["contacts-squat-jump"]:
        if args.check:
            sys.exit("docs/model.md: the squat jump's contact figures differ; run "
                     "python scripts/make_docs.py --presets")
        write_blocks("docs/model.md", contacts)
    if args.check:
        problems = check_optimise_spread()
        if problems:
            sys.exit("\n".join(problems))
    if args.presets:
        conventions_figures()
        result_figures()
    if args.check or args.presets:
        return
    from torquesim.cli import main as torquesim

    only = [p for p, flag in (("squat-jump", args.jump), ("drop-landing", args.landing)) if flag]
    if only:
        for preset in only:
            with tempfile.TemporaryDirectory() as tmp:
                write_blocks("docs/study.md", ground_blocks(torquesim, Path(tmp), preset))
            prefix = GROUND_STUDIES[preset][0]
            print(f"wrote the {prefix} blocks of docs/study.md and docs/figures/{prefix}_*.png")
        return
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "compare"
        code = torquesim(["compare", "--out", str(folder), "--quiet"])
        if code:
            sys.exit(f"torquesim compare failed (exit {code})")
        manifest = json.loads((folder / "manifest.json").read_text())
        blocks = {"study-verdict": verdict_block(folder, manifest),
                  "study-limits": limits_block(folder, manifest),
                  "default-checks": checks_block()}
        for name in FIGURES:
            shutil.copyfile(folder / name, ROOT / "docs" / "figures" / name)
        vary = Path(tmp) / "vary"
        code = torquesim(["compare", *SENSITIVITY, "--out", str(vary), "--quiet"])
        if code:
            sys.exit(f"torquesim compare --vary failed (exit {code})")
        shutil.copyfile(vary / "sensitivity.png", ROOT / "docs" / "figures" / "sensitivity.png")
        if not args.curl:
            for preset in GROUND_STUDIES:
                blocks.update(ground_blocks(torquesim, Path(tmp), preset))
    write_blocks("docs/study.md", blocks)
    print(f"wrote docs/figures/{{{','.join((*FIGURES, 'sensitivity.png'))}}}")


if __name__ == "__main__":
    main()
