"""Generated blocks of the documentation: the text between ``<!-- generated: NAME -->`` and
``<!-- end generated -->`` in a docs page is written by a script of the repository (the
study by ``scripts/make_docs.py``, the validation figures by ``scripts/validation_figures.py``,
the fit, optimisation, batch and first-run measurements by ``benchmarks/bench_fit.py
--write-docs``, ``benchmarks/bench_optimise.py --write-docs``, ``benchmarks/bench_batch.py
--write-docs`` and ``benchmarks/bench_cold_start.py --write-docs``), never typed by hand."""

from __future__ import annotations

import os
import re
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
BLOCK = re.compile(r"(<!-- generated: (?P<name>[a-z-]+) -->\n)(?P<body>.*?)"
                   r"(<!-- end generated -->)", re.S)
#: Every generated block, by page (checked by ``scripts/make_docs.py --check`` in CI).
PAGES = {
    "docs/study.md": {"study-verdict", "study-limits", "default-checks", "jump-verdict",
                      "jump-limits", "jump-stiffness", "landing-verdict", "landing-limits",
                      "landing-stiffness", "landing-speeds"},
    "docs/validation.md": {"validation-figures", "validation-ground"},
    "docs/fitting.md": {"fit-benchmark", "jump-unseen"},
    "docs/optimise.md": {"optimise-benchmark"},
    "docs/batch.md": {"batch-benchmark"},
    "docs/tutorial.md": {"cold-start"},
    "docs/concepts.md": {"techniques"},
    "docs/model-files.md": {"model-fields"},
    "docs/presets.md": {"motion-elbow-curl", "motion-knee-extension", "motion-arm-raise",
                        "motion-squat-jump", "motion-countermovement-jump",
                        "motion-squat-jump-biarticular", "motion-drop-landing"},
    "docs/model.md": {"contacts-squat-jump"},
    "README.md": {"test-suite", "chains-benchmark", "simulate-benchmark"},
    "docs/index.md": {"test-suite"},
}
#: The presets whose motion `preset_motion_blocks` describes, in page order.
MOTION_PRESETS = ("elbow-curl", "knee-extension", "arm-raise", "squat-jump",
                  "countermovement-jump", "squat-jump-biarticular", "drop-landing")


def techniques_block() -> str:
    """The technique registry (`torquesim.solvers.techniques.TECHNIQUES`) as a table: cheap,
    so ``make_docs.py --check`` also checks that the page shows the registry as it is."""
    from torquesim.solvers.techniques import TECHNIQUES

    lines = ["| technique | `--method` | how the parts are integrated | order | implicit | "
             "in the study |", "|---|---|---|---|---|---|"]
    for t in TECHNIQUES:
        order = "adaptive" if t.order is None else str(t.order)
        # plain text, not code spans: code spans break inside words in narrow table cells
        lines.append(f"| {t.name} | {t.method} | {t.parts} | {order} | {t.implicit} | "
                     f"{'yes' if t.in_study else 'no'} |")
    return ("Every technique torquesim knows, from its registry "
            "(`torquesim.solvers.techniques`; the order is the declared one, which the tests "
            "measure on two smooth cases):\n\n" + "\n".join(lines) + "\n")


def fields_block() -> str:
    """Every numeric field of a model file with its unit, meaning and allowed values, from the
    classes' `Allowed` tables (the ones their range checks and the files' comments read):
    cheap, so ``make_docs.py --check`` also checks that the page shows them as they are."""
    from torquesim.io.model_file import FIELD_TABLES

    lines = ["Every number of a model file, with the values allowed and its unit, from the "
             "tables the range checks and the files' comments read "
             "(`torquesim.model.fields.Allowed`)."]
    for section, table in FIELD_TABLES.items():
        where = section if section == "top level" else f"`{section}`"
        lines += ["", f"**{where}**", "", "| key | allowed | unit | what |", "|---|---|---|---|"]
        lines += [f"| `{name}` | {allowed.interval()} | {allowed.unit or '–'} | "
                  f"{allowed.meaning or '–'} |" for name, allowed in table.items()]
    return "\n".join(lines) + "\n"


def _swing(time, angle) -> str:
    """'start° → extreme° (t = …) → end°' of one joint's angle history (rad), the extreme
    being the sample farthest from the start."""
    deg = np.degrees(angle)
    k = int(np.argmax(np.abs(deg - deg[0])))
    return f"{deg[0]:.1f}° → {deg[k]:.1f}° (t = {time[k]:.2f} s) → {deg[-1]:.1f}°"


def preset_motion_blocks() -> dict[str, str]:
    """The motion of each preset as the reference solver (Radau) gives it, for
    docs/presets.md: per joint start → extreme (time) → end; for a body on the ground its
    take-off, centre-of-mass rise and peak ground reaction force, and for one that starts
    standing its countermovement (lowest point, least ground force). Cheap (seconds), so
    ``make_docs.py --check`` checks that the page shows the presets as they are."""
    import torquesim as ts

    blocks = {}
    for name in MOTION_PRESETS:
        model = ts.load_model(f"builtin:{name}")
        ground = model.base == "free"
        run = ts.simulate(model, "reference", output_step=1e-4 if ground else 1e-3)
        if ground and model.landing_speed:
            text = _landing_text(model, run)
        elif ground:
            e = run.ground_events()
            c = run.columns()
            i = int(np.searchsorted(run.time, e.take_off))
            end = "in the air" if e.landing is None else f"after landing at {e.landing:.3f} s"
            stops = [(np.abs(c[f"torque_passive_{j.name}"]).max(),
                      np.abs(c[f"torque_net_{j.name}"]).max(), j.name)
                     for j in model.joints if j.endstop_torque > 0]
            passive, peak, joint = max(stops, key=lambda s: s[0] / s[1])
            low = int(np.argmin(c["com_y"][:i]))
            drop = c["com_y"][0] - c["com_y"][low]
            start = "the squat"
            text = ""
            if drop > 0.05:  # a countermovement from standing
                start = "standing"
                least = int(np.argmin(c["grf_y"][:low]))
                text = (f"Countermovement (Radau): the centre of mass {drop:.3f} m down at "
                        f"{run.time[low]:.3f} s, the ground force falling to "
                        f"{c['grf_y'][least] / e.weight:.2f} body weights at "
                        f"{run.time[least]:.3f} s. ")
            text += (f"Motion (Radau): take-off at {e.take_off:.3f} s at "
                    f"{c['com_speed_y'][i]:.2f} m/s up and {c['com_speed_x'][i]:+.3f} m/s "
                    f"forwards; centre of mass {e.rise:.3f} m above {start} at its apex "
                    f"({e.apex_time:.3f} s), of which the flight adds {e.flight_height:.3f} m; "
                    f"peak ground reaction force {e.peak_force:.0f} N "
                    f"({e.peak_force / e.weight:.2f} body weights) at {e.peak_time:.3f} s. The "
                    f"largest end-stop torque is the {joint}'s, {passive:.2f} N·m "
                    f"({100 * passive / peak:.1f} % of its peak muscle torque, {peak:.0f} N·m). "
                    f"The run ends {end} at {model.duration:g} s.")
        else:
            parts = [f"{j.name} {_swing(run.time, run.q[:, k])}"
                     for k, j in enumerate(model.joints)]
            text = f"Motion (Radau): {'; '.join(parts)}, in {model.duration:g} s."
        blocks[f"motion-{name}"] = text + "\n"
    return blocks


def _landing_text(model, run) -> str:
    """A landing's motion: the touchdown, the peak ground force, how far the centre of mass
    sinks, the joints' swing, the end stops and whether the body stays on the ground."""
    e = run.ground_events()
    c = run.columns()
    low = int(np.argmin(c["com_y"]))
    stops = max(np.abs(c[f"torque_passive_{j.name}"]).max()
                for j in model.joints if j.endstop_torque > 0)
    parts = [f"{j.name} {_swing(run.time, run.q[:, k])}"
             for k, j in enumerate(model.joints) if j.name != model.joints[0].name]
    stays = "on the ground throughout" if np.all(c["grf_y"][1:] > 0.0) else \
        "leaving the ground in between"
    return (f"Motion (Radau): touchdown at {model.landing_speed:.2f} m/s; peak ground "
            f"reaction force {e.peak_force:.0f} N ({e.peak_force / e.weight:.1f} body weights) "
            f"at {1e3 * e.peak_time:.1f} ms; the centre of mass sinks "
            f"{c['com_y'][0] - c['com_y'][low]:.3f} m, lowest at {run.time[low]:.3f} s; "
            f"{'; '.join(parts)}; the largest end-stop torque {stops:.2f} N·m; {stays} to "
            f"{model.duration:g} s.")


def contact_blocks() -> dict[str, str]:
    """For docs/model.md §9: how far the squat jump's loaded contacts creep during the
    push-off and the contacts' smallest time constant over the run, at the preset's slip
    speed and two smaller ones (IMEX at a step well inside each one's limit; a few seconds)."""
    import dataclasses

    import torquesim as ts

    model = ts.load_model("builtin:squat-jump")
    preset_speed = model.contacts[0].slip_speed
    parts = []
    for speed, step in ((preset_speed, 1e-4), (0.1, 5e-5), (0.01, 5e-6)):
        varied = model.replace(contacts=tuple(dataclasses.replace(c, slip_speed=speed)
                                              for c in model.contacts))
        run = ts.simulate(varied, "imex", step, check=False, advise=False, tolerance=None)
        c = run.columns()
        off = int(np.searchsorted(run.time, run.ground_events().take_off))
        creep = {}
        for contact in model.contacts:
            x = c[f"{contact.point}_x"][:off][c[f"grf_y_{contact.point}"][:off] > 0]
            creep[contact.point] = 1e3 * (x.max() - x.min())
        tau = 1e3 * run.settings["contact_time_constant_min_s"]
        slid = [f"{p} {mm:.2f} mm" for p, mm in creep.items()]
        moved = f"the {slid[0].replace(' ', ' slides ', 1)}" + "".join(f", the {x}"
                                                                      for x in slid[1:])
        which = " (the preset)" if speed == preset_speed else ""
        parts.append(f"at v_s = {speed:g} m/s{which} {moved} while loaded, and the "
                     f"contacts' smallest time constant is {tau:.3g} ms")
    return {"contacts-squat-jump": "On the squat jump: " + "; ".join(parts) + ".\n"}


def current_block(page: str, name: str) -> str:
    """The body of generated block ``name`` of ``page`` as it stands."""
    text = (ROOT / page).read_text(encoding="utf-8")
    for m in BLOCK.finditer(text):
        if m.group("name") == name:
            return m.group("body")
    raise KeyError(name)


def blocks_in(page: str) -> set[str]:
    """Names of the generated blocks in ``page`` (a path relative to the repository)."""
    text = (ROOT / page).read_text(encoding="utf-8")
    return {m.group("name") for m in BLOCK.finditer(text)}


def missing_blocks() -> list[str]:
    """Pages whose generated blocks differ from `PAGES`, one message each."""
    problems = []
    for page, wanted in PAGES.items():
        found = blocks_in(page)
        if found != wanted:
            problems.append(f"{page}: generated blocks {sorted(found)}; expected "
                            f"{sorted(wanted)}")
    return problems


def write_blocks(page: str, blocks: dict[str, str]) -> None:
    """Replace the bodies of the named generated blocks of ``page``."""
    path = ROOT / page
    text = path.read_text(encoding="utf-8")
    missing = set(blocks) - blocks_in(page)
    if missing:
        raise SystemExit(f"{page}: no generated block {sorted(missing)}")
    text = BLOCK.sub(lambda m: m.group(1) + blocks.get(m.group("name"), m.group("body"))
                     + m.group(4), text)
    path.write_text(text, encoding="utf-8")
    print(f"rewrote {page} ({', '.join(sorted(blocks))})")


def measured_on(load_start: float) -> str:
    """'2026-12-01, 2 cores, load 0.8 → 1.1': when and under what load a block was measured."""
    return (f"{datetime.now(UTC).date()}, {os.cpu_count()} cores, load average "
            f"{load_start:.2f} → {os.getloadavg()[0]:.2f}")
