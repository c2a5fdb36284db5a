"""Command-line interface: ``torquesim simulate``, ``model``, ``compare``, ``fit``,
``optimise`` and ``batch``."""

from __future__ import annotations

import math
import re
import sys
from contextlib import contextmanager
from pathlib import Path

import click

from .errors import ModelError, SimulationError
from .model.preset_names import preset_list
from .solvers.techniques import (
    ERROR_CONTROL_ATOL,
    ERROR_CONTROLLED_METHODS,
    FIT_METHODS,
    FIXED_STEP_METHODS,
    GROUND_CONTROL_ATOL,
    METHODS,
    MIN_CONTROL_ATOL,
    TECHNIQUES,
    VELOCITY_SCALE,
)

PLOT_SUFFIXES = (".png", ".pdf", ".svg")
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}


class TimeValue(click.ParamType):
    """A time in seconds; accepts a unit suffix: ``0.1ms``, ``100us``, ``1e-4``, ``3s``."""

    name = "TIME"

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        m = re.fullmatch(r"\s*([-+0-9.eE]+)\s*(s|ms|us|µs)?\s*", str(value))
        try:
            number = float(m.group(1)) if m else math.nan
        except ValueError:
            number = math.nan
        if not m or not math.isfinite(number):
            self.fail(f"{value!r} is not a time (e.g. 0.0001, 0.1ms, 100us)", param, ctx)
        return number * _TIME_UNITS[m.group(2) or "s"]


TIME = TimeValue()


#: Room a file name must leave for the temporary name it is written under first (atomic
#: writes: ``.<name>.<pid>.tmp<suffix>``), bytes.
TEMPORARY_NAME_ROOM = 32


def _check_output(path: str | None, suffixes, option: str) -> None:
    """Refuse an output ``path`` before any work: unknown extension, a folder that does not
    exist or cannot be written in, a name too long to write, a directory or a read-only file
    of that name."""
    import os

    if path is None:
        return
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise ModelError(option, f"{path!r}: unknown extension; allowed {', '.join(suffixes)}")
    _check_writable_folder(p.parent, option, path)
    folder = str(p.parent) or "."
    try:
        longest = os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        longest = 255
    if len(p.name.encode()) + TEMPORARY_NAME_ROOM > longest:
        raise ModelError(option, f"{path!r}: a name of {len(p.name.encode())} bytes; allowed at "
                         f"most {longest - TEMPORARY_NAME_ROOM} bytes in this folder")
    if p.is_dir():
        raise ModelError(option, f"{path!r} is a directory; allowed: a file name")
    if p.exists() and not os.access(p, os.W_OK):
        raise ModelError(option, f"{path!r} exists and cannot be written; allowed: a file "
                         "this user may replace")


def _check_distinct_outputs(paths: dict[str, str | None]) -> None:
    """Refuse two outputs of one command written to the same file (one would overwrite the
    other, and a manifest would describe the wrong data): ``paths`` maps option → path."""
    seen: dict[Path, str] = {}
    for option, path in paths.items():
        if path is None:
            continue
        where = Path(path).resolve()
        if where in seen:
            raise ModelError(option, f"{path!r} is also the file of {seen[where]}; allowed: a "
                             "file of its own")
        seen[where] = option


def _check_out_folder(out: Path) -> None:
    """An --out folder: it, or the folder it will be made in, can be written in."""
    _check_writable_folder(out if out.is_dir() else out.parent, "--out", str(out))


def _check_writable_folder(folder: Path, option: str, path: str) -> None:
    """The folder an output ``path`` goes into exists and a file can be created in it (tried
    with a temporary file, removed at once: permissions alone do not tell, e.g. /proc)."""
    import tempfile

    folder = folder if str(folder) else Path(".")
    if not folder.is_dir():
        raise ModelError(option, f"directory {str(folder)!r} does not exist")
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".torquesim-probe-"):
            pass
    except OSError as exc:
        raise ModelError(option, f"cannot write {path!r}: nothing can be created in "
                         f"{str(folder)!r} ({exc.strerror or exc})") from None


CONTEXT = {"help_option_names": ["-h", "--help"]}


@click.group(context_settings=CONTEXT)
@click.version_option(package_name="torquesim")
@click.pass_context
def cli(context):
    """torquesim: torque-driven simulation of planar chains (default: an elbow dumbbell
    curl) with Hill-type torque generators.

    Compares the partitioned and monolithic solution of the body and muscle equations.
    SI units throughout; angles in radians in files, degrees in summaries.
    """
    if isinstance(context.obj, CompileReporter):
        context.obj.listen()


@cli.command(short_help="Simulate a model; print or write the motion.")
@click.option("--model", "model_path", default="builtin:elbow-curl", show_default=True,
              help=f"Model: a TOML file or a preset: {preset_list()} (see 'torquesim "
                   "model').")
@click.option("--method", type=click.Choice(METHODS),
              default="monolithic", show_default=True,
              help="monolithic: one RK4 on all equations; partitioned: each part its own RK4, "
                   "zero-order hold exchange; imex: body explicit RK4, muscles implicit "
                   "(L-stable SDIRK2), stable at large steps; imex-ros2: imex with the "
                   "body's end stops and ground contacts implicit too (ROS2), no step "
                   "limit from the contacts; imex-ros2-adaptive: imex-ros2 at steps chosen "
                   "by its error estimate (--atol), take-off and touchdown located; "
                   "reference: SciPy Radau, rtol 1e-10.")
@click.option("--step", type=TIME, default=None,
              help="Fixed step of the RK4 methods (s; suffixes ms/us accepted). Must divide "
                   "the duration. Default: 0.1 ms (else the largest step below it that "
                   "divides the duration), or where that breaks the explicit part's "
                   "stability limit on the model (stiff units or contacts), the largest step "
                   "a run verifies, said in a note.")
@click.option("--output-step", type=TIME, default=None,
              help="Output grid of the methods that choose their own steps (reference, "
                   "imex-ros2-adaptive; s, suffixes ms/us accepted): their state is written "
                   "at its multiples. Must divide the duration. Default: 1 ms (0.1 ms on a "
                   "body with ground contacts), else the largest step below it that divides "
                   "the duration.")
@click.option("--duration", type=TIME, default=None, help="Override the model's duration (s).")
@click.option("--out", "out_path", type=click.Path(dir_okay=False),
              help="Write the trajectory: .csv or OpenSim .sto/.mot (rad, SI), with a "
                   ".manifest.json beside it.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Write a figure of angle, torques and activations (.png, .pdf, .svg).")
@click.option("--animate", "animation_path", type=click.Path(dir_okay=False),
              help="Write the motion as a stick-figure animation (.gif), 25 frames per "
                   "simulated second.")
@click.option("--grf", "grf_path", type=click.Path(dir_okay=False),
              help="Models with ground contacts: write the ground reaction forces as an "
                   "OpenSim external-loads .mot (total at the centre of pressure, and per "
                   "contact point).")
@click.option("--atol", type=float, default=None,
              help="imex-ros2-adaptive: the angle tolerance of each step, rad (speeds "
                   f"{VELOCITY_SCALE:g}x it per second). Default {ERROR_CONTROL_ATOL:g}; "
                   f"{GROUND_CONTROL_ATOL:g} on a body with ground contacts (its ground "
                   "force's impulse then meets its momentum change within 1e-6). "
                   f"Bounds [{MIN_CONTROL_ATOL:g}, 1].")
@click.option("--tolerance", type=float, default=0.5, show_default=True,
              help="Fixed-step methods: estimate the max angle error against a run at twice "
                   "the step (half a run's work; at half the step when that is above the "
                   "tolerance); imex-ros2-adaptive: against a run at --atol 4x tighter and half "
                   "its largest step; and warn above this many degrees; 0 turns the estimate "
                   "off.")
def simulate(model_path, method, step, output_step, duration, out_path, plot_path,
             animation_path, grf_path, atol, tolerance):
    """Simulate the model and print a summary (or write --out / --plot)."""
    import numpy as np

    from .io.model_file import load_model
    from .solvers import simulate as run
    from .solvers.fixed_step import RK4_STABILITY_LIMIT as RK4_LIMIT

    _check_output(out_path, (".csv", ".sto", ".mot"), "--out")
    _check_output(plot_path, PLOT_SUFFIXES, "--plot")
    _check_output(animation_path, (".gif",), "--animate")
    _check_output(grf_path, (".mot",), "--grf")
    _check_distinct_outputs({"--out": out_path, "--out's manifest": out_path and
                             f"{out_path}.manifest.json", "--plot": plot_path,
                             "--animate": animation_path, "--grf": grf_path})
    compiling_for(f"the model's checks ({model_path})")
    model = load_model(model_path)
    if grf_path and not model.contacts:
        raise ModelError("--grf", f"{model.name} has no ground contacts; allowed: a model "
                         "with [[contacts]]")
    controlled = method in ERROR_CONTROLLED_METHODS
    fixed = method in FIXED_STEP_METHODS
    if step is not None and controlled:
        raise ModelError("--step", f"method {method!r} chooses its own steps; allowed: "
                         f"--step with {', '.join(FIXED_STEP_METHODS)}")
    if output_step is not None and fixed:
        raise ModelError("--output-step", f"method {method!r} writes every step (--step); "
                         "allowed: --output-step with the methods that choose their own "
                         "steps (reference, " + ", ".join(ERROR_CONTROLLED_METHODS) + ")")
    if atol is not None and not controlled:
        raise ModelError("--atol", f"only method {', '.join(ERROR_CONTROLLED_METHODS)} takes "
                         "an angle tolerance")
    check = None if tolerance == 0 else _tolerance_rad(tolerance, "--tolerance")
    _announce_size(model, method, step or output_step, duration, out_path)
    compiling_for(f"the {method} technique for {model_kind(model)}")
    result = run(model, method, step, duration=duration, atol=atol, output_step=output_step,
                 tolerance=check if fixed or controlled else None,
                 progress=_after_a_while(SEARCH_REPORT_AFTER))
    if result.settings.get("step_note"):
        click.echo(f"note: {result.settings['step_note']}", err=True)
    if result.message:
        click.echo(f"warning: {result.message}", err=True)
    if out_path:
        from .io.tables import save_result

        save_result(result, out_path, "--out")
    if plot_path:
        from .plots import plot_result, save_figure

        save_figure(plot_result(result), plot_path, "--plot")
    if animation_path:
        from .plots import animate_result

        animate_result(result, animation_path)
    if grf_path:
        from .io.tables import save_ground_reactions

        save_ground_reactions(result, grf_path)
    lines = [
        f"model         {result.model.name} ({result.model.n_joints} joint"
        f"{'s' if result.model.n_joints > 1 else ''}, {result.model.n_units} units)",
        f"method        {result.method}"
        + (f", step {result.step * 1e3:g} ms" if result.step else
           f", atol {result.settings['atol']:g} rad: steps "
           f"{result.settings['smallest_step'] * 1e3:.3g}–"
           f"{result.settings['largest_step'] * 1e3:.3g} ms, "
           f"{result.settings['rejected_steps']} rejected, {result.settings['events']} "
           "events located" if controlled else f", rtol {result.settings['rtol']:g}"),
        f"duration      {result.time[-1]:g} s",
    ]
    for joint in result.model.joints:
        angle = result.angle(joint.name)
        low, high = int(np.argmin(angle)), int(np.argmax(angle))
        lines.append(f"{joint.coordinate:13s} min {math.degrees(angle[low]):.4f} deg at t = "
                     f"{result.time[low]:.4f} s, peak {math.degrees(angle[high]):.4f} deg at "
                     f"t = {result.time[high]:.4f} s, final {math.degrees(angle[-1]):.4f} deg")
    events = result.ground_events()
    if events is not None:
        lines += events.summary_lines()
    lines += [
        f"steps         {result.cost.steps if result.cost.steps >= 0 else 'adaptive'}",
        f"rhs evals     body {result.cost.rhs_body}, muscle {result.cost.rhs_muscle}",
        f"wall time     {result.cost.wall_time * 1e3:.1f} ms",
    ]
    estimate = result.settings.get("estimated_error_rad")
    if estimate is not None:
        lines.append(f"error est.    {math.degrees(estimate):.3g} deg max "
                     f"({result.settings['error_estimate']}; tolerance {tolerance:g} deg)")
    report = result.stability
    if report is not None:
        tau_min = report.step / report.max_step_ratio if report.max_step_ratio > 0 else \
            math.inf
        limit = ("muscles implicit, no step limit from τ" if math.isinf(report.limit)
                 else f"RK4 limit 2.785·τ_min = {RK4_LIMIT * tau_min * 1e3:.3g} ms"
                 if report.verified_step is None else
                 f"checked safe step {report.largest_safe_step * 1e3:.4g} ms")
        lines.append(f"stability     max step/τ {report.max_step_ratio:.3g} "
                     f"({report.unit}), τ_min {tau_min * 1e3:.3g} ms; {limit}")
    if out_path:
        lines.append(f"wrote         {out_path}")
    if plot_path:
        lines.append(f"wrote         {plot_path}")
    if animation_path:
        lines.append(f"wrote         {animation_path}")
    if grf_path:
        lines.append(f"wrote         {grf_path}")
    click.echo("\n".join(lines))


#: A run longer than this many steps, or a table larger than this many bytes, is announced
#: before it starts (with how to make it smaller).
LARGE_RUN_STEPS = 2_000_000
LARGE_TABLE_BYTES = 200e6


#: simulate's search for a step a run verifies says each step it tries once it has run this
#: long (s); a short search stays silent.
SEARCH_REPORT_AFTER = 2.0


def _after_a_while(seconds: float):
    """A ``progress(text)`` that writes ``note: text`` to stderr once ``seconds`` have passed
    since its first call (the first call only starts the clock)."""
    import time

    start = []

    def say(text: str) -> None:
        if not start:
            start.append(time.monotonic())
        elif time.monotonic() - start[0] >= seconds:
            click.echo(f"note: {text}", err=True)
    return say


#: While a command compiles, a line at least this often (s), so that a log is never silent
#: for longer.
COMPILE_REPORT_INTERVAL = 10.0
#: The one line said when a command starts compiling (only when Numba's cache on disk lacks
#: what it runs): what is compiled and that other kinds of run compile their own code.
COMPILING_NOTICE = ("compiling {subject} with Numba: once per technique and kind of model on "
                    "this install (10-60 s); later runs of this kind start in seconds, other "
                    "techniques and models compile on their first run ...")
#: What a command compiles, until it says (`compiling_for`).
DEFAULT_SUBJECT = "the model's checks and the integrators this command runs"


def model_kind(model) -> str:
    """The kind of model a compiled step loop is made for, as the compile notice names it."""
    from .model.chain import as_chain

    model = as_chain(model)
    if model.contacts:
        kind = f"a free body on {len(model.contacts)} ground contacts"
    elif model.base == "free":
        kind = "a free body"
    else:
        kind = (f"a {model.n_joints}-joint chain" if model.n_joints > 1 else
                "a one-joint chain")
    if any(u.activation_dynamics is not None for u in model.units):
        kind += " with activation dynamics"
    return f"{kind} ({model.name})"


def compiling_for(subject: str) -> None:
    """Name what the current command compiles, for the compile notice."""
    context = click.get_current_context(silent=True)
    reporter = context.find_root().obj if context is not None else None
    if isinstance(reporter, CompileReporter):
        reporter.subject = subject


class CompileReporter:
    """Tells the user when Numba compiles: `COMPILING_NOTICE` (naming the ``subject`` a
    command set with `compiling_for`; again when a later compile has another subject, e.g.
    the model's checks, then the technique's loop) on stderr when a command first
    compiles (not before: bad input fails without it; nothing when every kernel is on disk),
    then "still compiling (N s)" every ``interval`` s while that compiling goes on. It listens
    to Numba's "numba:compile" events, which fire only for a compile (a cache miss), and
    reports from a daemon thread, which the compiler leaves time to run. A context manager;
    ``quiet`` says nothing."""

    def __init__(self, interval: float = COMPILE_REPORT_INTERVAL, echo=None,
                 quiet: bool = False):
        self.subject = DEFAULT_SUBJECT
        self.announced = None  # the subject the notice last named
        self.interval = interval
        self.echo = echo or (lambda text: click.echo(text, err=True))
        self.quiet = quiet
        self.depth = 0  # nested compiles under way
        self.burst_start = None  # when the compiles now under way began (monotonic s)
        self.thread = None
        self._closed = False
        self._listener = None

    def on_start(self, _event=None) -> None:
        import time

        self.depth += 1
        if self.depth == 1:
            self.burst_start = time.monotonic()
            if not self.quiet and self.subject != self.announced:
                self.echo(self.notice)  # once per subject: a command names what it compiles
                self.announced = self.subject
                if self.thread is None:
                    self.thread = self._start_watching()

    @property
    def notice(self) -> str:
        """`COMPILING_NOTICE` for what this command compiles."""
        return COMPILING_NOTICE.format(subject=self.subject)

    def on_end(self, _event=None) -> None:
        self.depth = max(self.depth - 1, 0)
        if self.depth == 0:
            self.burst_start = None

    def _start_watching(self):
        import threading
        import time

        def watch() -> None:
            reported, burst = 0, None
            while not self._closed:
                time.sleep(min(0.25, self.interval / 4))
                start = self.burst_start
                if start is None:
                    continue
                if start != burst:
                    reported, burst = 0, start
                elapsed = time.monotonic() - start
                if elapsed >= (reported + 1) * self.interval:
                    reported = int(elapsed // self.interval)
                    self.echo(f"still compiling ({elapsed:.0f} s) ...")

        thread = threading.Thread(target=watch, name="torquesim-compiling", daemon=True)
        thread.start()
        return thread

    def listen(self) -> None:
        """Start listening to Numba (imports it: called when a command runs, so that
        ``torquesim --help`` stays quick)."""
        from numba.core import event

        listener = self

        class _Listener(event.Listener):
            def on_start(self, event_):
                listener.on_start(event_)

            def on_end(self, event_):
                listener.on_end(event_)

        if self._listener is None:
            self._listener = _Listener()
            event.register("numba:compile", self._listener)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self._closed = True
        if self._listener is not None:
            from numba.core import event

            event.unregister("numba:compile", self._listener)
            self._listener = None


def _quiet_compiling(quiet: bool) -> None:
    """A command's ``--quiet`` silences the `CompileReporter` too."""
    context = click.get_current_context(silent=True)
    reporter = context.find_root().obj if context is not None else None
    if quiet and isinstance(reporter, CompileReporter):
        reporter.quiet = True


def _announce_size(model, method, step, duration, out_path) -> None:
    """One line on stderr before a run whose steps or output table are large (``step``: a
    fixed-step method's step, or the output grid of the others; None: the default,
    `simulate`'s first choice)."""
    from .errors import check_range
    from .solvers.simulation import default_fixed_step, default_output_step, step_count

    span = model.duration if duration is None else check_range(
        "duration", duration, 0.0, 600.0, low_open=True, unit="s")
    if method not in FIXED_STEP_METHODS:  # the reference: its output grid
        rows = round(span / (step or default_output_step(span, bool(model.contacts)))) + 1
        steps = 0
    else:
        steps = step_count(span, step or default_fixed_step(span))
        rows = steps + 1
    columns = 1 + 3 * model.n_joints + 4 * model.n_units
    size = rows * columns * 23  # a float written in full precision, with its separator
    if steps > LARGE_RUN_STEPS or (out_path and size > LARGE_TABLE_BYTES):
        what = f"{steps:,} steps" + (f", a table of about {size / 1e6:,.0f} MB in {out_path}"
                                     if out_path else "")
        click.echo(f"note: this run takes {what}; a larger --step or a shorter --duration "
                   "makes it smaller", err=True)


def conventions_figure(chain):
    """`plots.plot_conventions` of ``chain``, with the default OpenSim maps when its joints
    are the squat jump's."""
    from .fitting.coordinate_map import DEFAULT_MAPS, default_map
    from .plots import plot_conventions

    maps = None
    if [j.name for j in chain.joints][:4] == ["foot_ground", "ankle", "knee", "hip"]:
        maps = {name: default_map(name, chain) for name in DEFAULT_MAPS}
    return plot_conventions(chain, maps)


@cli.command(short_help="Write a model as an editable TOML file.")
@click.argument("name", default="elbow-curl")
@click.option("--out", "out_path", type=click.Path(dir_okay=False),
              help="Where to write the model TOML.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Draw the model (segments, joints, loads, which units act where) and each "
                   "unit's property curves (.png, .pdf, .svg).")
@click.option("--conventions", "conventions_path", type=click.Path(dir_okay=False),
              help="Draw how the model's angles are measured (zero line, positive way, units "
                   "on each joint; for the squat jump's joints also the OpenSim maps) (.png, "
                   ".pdf, .svg).")
@click.option("--body-mass", type=float, default=None,
              help="Make the built-in model for a subject of this body mass (kg, 20-250; "
              "with --height): segments from de Leva (1996), strengths scaled by size, sex "
              "and age (Anderson et al. 2007).")
@click.option("--height", type=float, default=None,
              help="The subject's standing height (m, 1.0-2.5; with --body-mass).")
@click.option("--sex", type=click.Choice(["male", "female"]), default=None,
              help="The subject's sex, for de Leva's segment tables and Anderson's strengths "
                   "(with --measurements: strengths only). Default: male.")
@click.option("--age", type=float, default=None,
              help="The subject's age (years, 18-100), for Anderson et al.'s (2007) strengths "
                   "by age. Default: a young adult (18-25), as the presets.")
@click.option("--measurements", "measurements", type=click.Path(dir_okay=False), default=None,
              help="Make the built-in model from the subject's own measurements: a Yeadon "
                   "measurement file (95 lengths, perimeters and widths; the yeadon package's "
                   "meastemplate.txt). --body-mass then scales the densities to the weighed "
                   "mass and --height (default: from the measurements) scales the strengths.")
@click.option("--densities", type=click.Choice(["Dempster", "Chandler", "Clauser"]),
              default="Dempster", show_default=True,
              help="Segment densities of Yeadon's model (with --measurements).")
@click.option("--paths", "list_paths", is_flag=True,
              help="Print every parameter path of the model (what --vary, --bound, --freeze "
                   "and --free take) with its value, SI unit and allowed range.")
def model(name, out_path, plot_path, conventions_path, body_mass, height, sex, age,
          measurements, densities, list_paths):
    """Write a model as an editable TOML file: a preset (NAME is one of the presets listed by
    `torquesim simulate --help`; builtin: prefix optional), made for a subject with
    --body-mass and --height (de Leva) or --measurements (Yeadon), or a checked, rewritten
    copy of a model file; or draw it with --plot, its angle conventions with --conventions;
    or list its parameter paths with --paths."""
    from .io.model_file import load_model, save_model
    from .model.presets import PREFIX, PRESETS

    if name not in PRESETS and not name.startswith(PREFIX) and not Path(name).exists():
        raise ModelError("NAME", f"{name!r} is neither a built-in model nor a file; allowed: "
                         f"{', '.join(PRESETS)} or a model file")
    if out_path is None and plot_path is None and conventions_path is None and not list_paths:
        raise ModelError("--out", "nothing to write; allowed: --out FILE.toml, --plot FILE.png, "
                         "--conventions FILE.png and/or --paths")
    _check_output(out_path, (".toml",), "--out")
    _check_output(plot_path, PLOT_SUFFIXES, "--plot")
    _check_output(conventions_path, PLOT_SUFFIXES, "--conventions")
    source = PREFIX + name if name in PRESETS else name
    chain = load_model(source)
    personal = (body_mass is not None or height is not None or sex is not None
                or age is not None)
    if (personal or measurements is not None) and not source.startswith(PREFIX):
        option = "--measurements" if measurements is not None else "--body-mass"
        raise ModelError(option, f"{name!r} is a model file; allowed: a built-in model "
                         f"({', '.join(PRESETS)}), whose segments are de Leva's")
    options = {"body_mass": "--body-mass", "height": "--height", "age": "--age"}
    if personal or measurements is not None:
        from .model.anthropometry import check_subject_value

        given = {"body_mass": body_mass, "height": height, "age": age}
        for field, value in given.items():  # each value given is checked before what is missing
            if value is not None:
                check_subject_value(field, value, options[field])
    if measurements is not None:
        from .model.anthropometry import for_measured
        from .model.yeadon_body import read_measurements

        body = read_measurements(measurements, body_mass, densities)
        for said in body.warnings:
            click.echo(f"note: yeadon: {said}", err=True)
        try:
            chain = for_measured(chain, body, body_mass, height, sex or "male", age)
        except ModelError as exc:
            raise _as_option(exc, options) from None
        click.echo(f"measured body {body.mass:.1f} kg, standing height "
                   f"{body.height if height is None else height:.3f} m"
                   f"{' (from the measurements)' if height is None else ''}")
    elif personal:
        from .model.anthropometry import Subject, for_subject

        if body_mass is None or height is None:
            missing = "--body-mass" if body_mass is None else "--height"
            raise ModelError(missing, "required to make a model for a subject; allowed: "
                             "--body-mass KG --height M [--sex male|female] [--age Y], or "
                             "--measurements FILE")
        try:
            chain = for_subject(chain, Subject(body_mass, height, sex or "male", age))
        except ModelError as exc:
            raise _as_option(exc, options) from None
    if out_path:
        save_model(chain, out_path, "--out")
        click.echo(f"wrote {out_path}")
    if plot_path:
        from .plots import plot_model, save_figure

        save_figure(plot_model(chain), plot_path, "--plot")
        click.echo(f"wrote {plot_path}")
    if conventions_path:
        from .plots import save_figure

        save_figure(conventions_figure(chain), conventions_path, "--conventions")
        click.echo(f"wrote {conventions_path}")
    if list_paths:
        click.echo(paths_table(chain))


def paths_table(chain) -> str:
    """Every parameter path of ``chain`` (`model.paths.model_paths`) with its value, SI unit
    and allowed range, one line each under a header."""
    from .model.paths import allowed_at, get_parameter, model_paths

    rows = [("path", "value", "unit", "allowed")]
    for path in model_paths(chain):
        allowed = allowed_at(chain, path)
        rows.append((path, f"{get_parameter(chain, path):.6g}", allowed.unit or "-",
                     allowed.interval()))
    widths = [max(len(row[k]) for row in rows) for k in range(3)]
    return "\n".join("  ".join([*(row[k].ljust(widths[k]) for k in range(3)), row[3]])
                     for row in rows)


class Progress:
    """Progress bars (tqdm) on stderr for the long commands, and their occasional lines.

    Bars are drawn only when stderr is a terminal; ``quiet`` silences bars and lines alike.
    ``step(done, total, label)`` advances the bar of the current phase (a new ``total``
    starts a new bar); ``done == total == 0`` announces a phase by its ``label``.
    """

    #: Without a terminal (a log file, CI), a progress line at least this often, s.
    LOG_EVERY = 10.0

    def __init__(self, quiet: bool):
        import time

        self.quiet = quiet
        self.bars = not quiet and sys.stderr.isatty()
        self.bar = None
        self.clock = time.monotonic
        self.last_line = self.clock()

    def say(self, message: str) -> None:
        if self.quiet:
            return
        if self.bar is not None:
            from tqdm import tqdm

            tqdm.write(message, file=sys.stderr)
        else:
            click.echo(message, err=True)
        self.last_line = self.clock()

    def step(self, done: int, total: int, label: str) -> None:
        if total <= 0:
            self.close()
            self.say(label)
            return
        if not self.bars:
            if not self.quiet and self.clock() - self.last_line >= self.LOG_EVERY:
                self.say(f"{label}: {done}/{total}")
            return
        from tqdm import tqdm

        if self.bar is None or self.bar.total != total or done < self.bar.n:
            self.close()
            self.bar = tqdm(total=total, file=sys.stderr, leave=False, dynamic_ncols=True)
        self.bar.set_postfix_str(label, refresh=False)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def _parse_steps(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(x) * 1e-3 for x in text.split(",") if x.strip())
    except ValueError:
        raise ModelError("--steps", f"{text!r}: allowed a comma-separated list of steps in "
                         "ms, e.g. 1,0.5,0.1") from None
    if not values:
        raise ModelError("--steps", "allowed a non-empty comma-separated list of steps in ms")
    return values


@cli.command(short_help="The study: every technique, accuracy vs cost.")
@click.option("--model", "model_path", default="builtin:elbow-curl", show_default=True,
              help=f"Model: a TOML file or a preset: {preset_list()}.")
@click.option("--steps", default=None,
              help="Fixed steps to try, in ms, comma-separated; each must divide the duration. "
                   "Default: those of 20, 10, 5, 2, 1, 0.5, 0.2, 0.1, 0.05 that divide the "
                   "model's duration (all nine on the presets but the squat jump, whose 0.55 s "
                   "drops 20).")
@click.option("--repeats", type=click.IntRange(1, 50), default=5, show_default=True,
              help="Runs per setting, interleaved round-robin over all settings; the minimum "
                   "wall time is reported with the spread (the ranking uses the modelled cost, "
                   "which does not move with load).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="compare-out",
              show_default=True, help="Directory for results.csv, figures, report.html.")
@click.option("--vary", metavar="NAME=V1,V2,...",
              help="Repeat the study per value of one parameter: a model path as in `batch "
                   "sweep` and `fit --bound` (e.g. elbow_flexor.se_stiffness, "
                   "forearm_hand.dumbbell.mass, elbow_extensor.ramp1.level), or one field of "
                   "every unit / extensor / point load at once: se_stiffness (N·m/rad), "
                   "extensor_level (constant co-activation), dumbbell_mass (kg), ce_damping "
                   "(N·m·s/rad); writes sensitivity.csv/.png/.html and one study folder per "
                   "value.")
@click.option("--quiet", is_flag=True, help="No progress bar or progress lines.")
def compare(model_path, steps, repeats, out_dir, vary, quiet):
    """Every technique over a range of steps against the reference: accuracy, order,
    stability and cost, and the verdict."""
    _quiet_compiling(quiet)
    _check_out_folder(Path(out_dir))
    from .io.model_file import load_model
    from .solvers.simulation import step_count
    from .study.compare import default_steps, verdict, verdict_sentences
    from .study.outputs import write_study

    compiling_for(f"the model's checks ({model_path})")
    model = load_model(model_path)
    compiling_for(f"every technique of the study for {model_kind(model)}")
    values = default_steps(model) if steps is None else _parse_steps(steps)
    for h in values:
        step_count(model.duration, h, "--steps")

    reporter = Progress(quiet)
    progress = reporter.step

    if vary:
        from .study.sensitivity import parse_vary, write_sensitivity

        name, vary_values = parse_vary(vary)
        summary = write_sensitivity(out_dir, model, name, vary_values, steps=values,
                                    repeats=repeats, progress=progress,
                                    model_source=model_path)
        reporter.close()
        for value in vary_values:
            picks = [r for r in summary if r["value"] == value]
            smallest = min(values) * 1e3
            largest = max(values) * 1e3
            limits = ", ".join(f"{r['technique']} " + (
                ("≥ " if r["stability_limit_s"] * 1e3 >= largest else "")
                + f"{r['stability_limit_s'] * 1e3:g} ms" if r["stability_limit_s"]
                else f"< {smallest:g} ms") for r in picks if r["technique"] in
                {t.name for t in TECHNIQUES if t.headline})
            winners = ", ".join(f"{t:g}°: {picks[0][f'cheapest_{t:g}deg'] or 'none'}"
                                for t in (1.0, 0.1, 0.01, 0.001))
            click.echo(f"{name} = {value:g}: stability limits {limits}; cheapest {winners}")
        click.echo(f"wrote {out_dir}/sensitivity.csv, sensitivity.png, sensitivity.html and "
                   f"one study folder per value")
        return

    rows, _, smooth = write_study(out_dir, model, steps=values, repeats=repeats,
                                  progress=progress, model_source=model_path)
    reporter.close()
    names = list(dict.fromkeys(r["technique"] for r in rows))
    click.echo("\n".join(verdict_sentences(verdict(rows), names)))
    click.echo(f"wrote {out_dir}/results.csv, verdict.csv, report.html, convergence.png, "
               "work_precision.png, time_constants.png, manifest.json")


def _parse_pairs(values, option: str, example: str) -> dict[str, str]:
    """``KEY=VALUE`` options as a dict of strings (`parse_assignment`, the one syntax of
    ``--vary``, ``--bound`` and ``--freeze``); a key given twice is an error."""
    from .model.paths import parse_assignment

    out = {}
    for text in values:
        key, value = parse_assignment(text, option, example)
        if key in out:
            raise ModelError(option, f"{key!r} is given twice; allowed: once")
        out[key] = value
    return out


def _parse_assignments(values, option: str, count: int) -> dict[str, tuple[float, ...]]:
    """``NAME=V`` (count 1) or ``NAME=LO,HI`` (count 2; ``LO..HI`` too, as ``--constrain``
    writes a range) options as a dict."""
    shape, example = (("NAME=VALUE", "flexor.ramp1.delay=0.05") if count == 1
                      else ("NAME=LOW,HIGH (or LOW..HIGH)", "flexor.ramp1.delay=0,0.5"))
    out = {}
    for name, text in _parse_pairs(values, option, example).items():
        ranged = count == 2 and ".." in text
        parts = [v.strip() for v in (text.split("..") if ranged else text.split(","))]
        # in LOW..HIGH no number starts or ends with a dot ("0...1": 0..0.1 or 0...1?)
        ambiguous = ranged and any(v.startswith(".") or v.endswith(".") for v in parts)
        try:
            numbers = () if ambiguous else tuple(float(v) for v in parts)
        except ValueError:
            numbers = ()
        if len(numbers) != count:
            raise ModelError(option, f"{name}={text!r}: allowed {shape}, e.g. {example}")
        if count == 2 and not numbers[0] < numbers[1]:
            raise ModelError(option, f"{name}={text!r}: allowed LOW < HIGH")
        out[name] = numbers
    return out


#: The fit technique and search options, shared by ``fit`` and ``batch fit``.
_SEARCH_OPTIONS = (
    click.option("--method", type=click.Choice(FIT_METHODS),
                 default="imex", show_default=True,
                 help="Technique inside the fit. Explicit RK4 (monolithic, partitioned) needs "
                      "a step ≤ ~0.25 ms on the default model; runs that break its stability "
                      "limit score as failed."),
    click.option("--step", type=TIME, default=None,
                 help="Fixed step (s; ms/us suffixes); the largest step not above it that "
                      "divides the target's span is used. Default: 5 ms; on a body on the "
                      "ground the largest of 5, 2.5, 1, 0.5, 0.25, 0.1 … ms within 0.7 of its "
                      "contacts' stability limit on the model's own run (0.25 ms on "
                      "builtin:squat-jump)."),
    click.option("--search", type=click.Choice(["least-squares", "global"]),
                 default="least-squares", show_default=True,
                 help="least-squares: trust-region least squares with a parallel "
                      "finite-difference Jacobian from the inverse-dynamics start and perturbed "
                      "starts (seconds); global: differential evolution + Nelder-Mead (robust, "
                      "~10x the simulations)."),
    click.option("--starts", type=click.IntRange(1, 100), default=4, show_default=True,
                 help="least-squares: starting points screened (inverse dynamics + perturbed)."),
    click.option("--iterations", type=click.IntRange(1, 100_000), default=200, show_default=True,
                 help="least-squares: residual evaluations refining the best start."),
    click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=1, show_default=True,
                 help="Random seed of the perturbed starts (and of the global search): the "
                      "same seed gives the same fit."),
)


def _search_options(fn):
    for option in reversed(_SEARCH_OPTIONS):
        fn = option(fn)
    return fn


def _search_folder(out_dir: str, resume: bool, overwrite: bool, files, what: str) -> Path:
    """The --out folder of a search (fit, optimisation): a directory (or a new one in an
    existing one) that holds none of ``files`` unless --resume or --overwrite says what to do
    with the earlier ``what``."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ModelError("--out", f"{out_dir!r} is a file; allowed: a directory")
    _check_out_folder(out)
    if resume and overwrite:
        raise ModelError("--overwrite", "contradicts --resume; allowed: one of them")
    if not resume and not overwrite and any((out / f).exists() for f in files):
        raise ModelError("--out", f"{out_dir!r} holds an earlier {what}; allowed: --resume "
                         "to continue it or --overwrite to replace it")
    return out


@cli.command(short_help="Fit activation ramps to a measured motion.")
@click.option("--target", "target_spec", default=None,
              help="Measured motion: a .csv (a time column and angle columns) or OpenSim "
                   ".mot/.sto (inverse kinematics: one column per coordinate), or a built-in "
                   "motion (builtin:curl, or a preset's name: its own motion). On a body on the "
                   "ground, columns grf_x, grf_y (N), com_x, com_y (m) are scored too. "
                   "Default: the model preset's own (builtin:curl for the elbow).")
@click.option("--column", "columns", multiple=True, metavar="JOINT=COLUMN",
              help="Target column of a joint (repeatable). Default: matched by name (the "
                   "joint's coordinate, e.g. elbow_flexion, its name, or the only column "
                   "containing its name). On a one-joint model a bare COLUMN works. Joints "
                   "without a column are simulated, not scored. Also grf_y=COLUMN etc. for a "
                   "ground reaction force or centre-of-mass column of another name. COLUMN "
                   "may be an expression in degrees: knee=-knee_angle_r, ankle=118-ankle_angle_r.")
@click.option("--map", "map_spec", default=None, metavar="NAME|FILE.toml",
              help="Joint angles from a 3D IK file's coordinates: gait2392 or rajagopal2016 "
              "(the squat jump's joints from the right leg, pelvis and lumbar), or a TOML file "
              "with a [targets.map] table of JOINT = \"EXPRESSION\"; --column overrides.")
@click.option("--forces", "forces_path", type=click.Path(dir_okay=False), default=None,
              help="A force-plate file (OpenSim external loads .mot/.sto or CSV, "
              "ground_force_vx/vy per plate; or a .c3d file's force platforms, --lab-axes): "
              "plates summed, low-passed, resampled onto the target's times and fitted as "
              "grf_x, grf_y (--grf-components).")
@click.option("--lab-axes", default="x,z", show_default=True,
              help="A .c3d --forces file's lab frame: the axis pointing forwards (the jumper "
              "facing it) and the one pointing up, e.g. x,z or -y,z.")
@click.option("--grf-cutoff", type=float, default=50.0, show_default=True,
              help="Cut-off of the zero-lag Butterworth low-pass on --forces, Hz.")
@click.option("--grf-components", type=click.Choice(["y", "xy"]), default="xy",
              show_default=True,
              help="Which --forces components are fitted: the vertical (y) or both (xy).")
@click.option("--rezero", is_flag=True,
              help="Subtract the force plates' reading in flight (a drifting zero offset) "
              "instead of refusing the file.")
@click.option("--angle-units", "--units", "units", type=click.Choice(["deg", "rad"]),
              help="Units of the target angles (CSV default deg; .mot/.sto: inDegrees).")
@click.option("--model", "model_path", default="builtin:elbow-curl", show_default=True,
              help=f"Model: a TOML file or a preset: {preset_list()}. Every unit's activation "
                   "is fitted as 3 ramps (9 parameters per unit).")
@_search_options
@click.option("--generations", type=click.IntRange(0, 100_000), default=300,
              show_default=True, help="global: differential-evolution generations.")
@click.option("--population", type=click.IntRange(2, 100), default=10, show_default=True,
              help="global: population per free parameter.")
@click.option("--polish", type=click.IntRange(0, 10**7), default=4000, show_default=True,
              help="global: Nelder-Mead simulations after the search.")
@click.option("--max-time", type=TIME, default=None,
              help="Optional wall-time cap (s); a capped fit depends on machine speed.")
@click.option("--rest-level", "--extensor-rest", "rest_level", type=float, default=None,
              help="Initial (rest) activation of the units that do not start from "
                   "equilibrium (the antagonists), not fitted. Default: the model's (0.1 for "
                   "the elbow extensor).")
@click.option("--bound", "bounds", multiple=True, metavar="NAME=LOW,HIGH",
              help="Change a parameter's bounds (repeatable), e.g. "
                   "elbow.flexor.ramp1.delay=0,0.5 (UNIT.rampK.FIELD; UNIT a unit name such as "
                   "elbow_flexor, or JOINT.flexor or JOINT.extensor). Defaults: delays 0-1 s, "
                   "durations 0.05-0.8 s, levels 0-1. A model field's path (SI) fits that "
                   "field too, from the model's value: toe.stiffness=1e6,1e7, "
                   "elbow_flexor.se_stiffness=300,900 (see torquesim model NAME --paths).")
@click.option("--freeze", "frozen", multiple=True, metavar="NAME=VALUE",
              help="Hold a parameter fixed (repeatable), e.g. elbow.extensor.ramp1.level=0.1; "
                   "a model field's path holds that field at VALUE (SI) in the fitted model.")
@click.option("--weight", "joint_weights", multiple=True, metavar="JOINT=W",
              help="Weight of a joint's angle error (repeatable; default 1 each, normalised).")
@click.option("--weight-velocity", type=float, default=0.0, show_default=True,
              help="Weight of the RMS angular-velocity error (deg/s x 1 s) in the objective.")
@click.option("--weight-end", type=float, default=0.0, show_default=True,
              help="Weight of the end angle and velocity errors in the objective.")
@click.option("--weight-effort", type=float, default=0.0, show_default=True,
              help="Weight (deg² per activation²) of the effort: Σ over units of the mean "
                   "squared activation above rest, so that among equal fits the least "
                   "co-contraction wins (e.g. 10).")
@click.option("--weight-grf", type=click.FloatRange(0.0, 1e4), default=20.0, show_default=True,
              help="Weight (deg per body weight) of the target's ground reaction force "
                   "columns: with 20, an RMS error of 5 % of body weight counts as 1 deg.")
@click.option("--weight-com", type=click.FloatRange(0.0, 1e5), default=100.0,
              show_default=True,
              help="Weight (deg per m) of the target's centre-of-mass columns: with 100, "
                   "1 cm RMS counts as 1 deg.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="fit-out",
              show_default=True, help="Directory for the fitted model, tables, figure, "
                                      "summary and checkpoint.")
@click.option("--resume", is_flag=True, help="Continue from OUT/fit_checkpoint.npz.")
@click.option("--overwrite", is_flag=True,
              help="Start a new fit in an --out directory that holds an earlier one.")
@click.option("--quiet", is_flag=True, help="No progress bar or progress lines.")
def fit(target_spec, columns, map_spec, forces_path, lab_axes, grf_cutoff, grf_components,
        rezero, units, model_path,
        method, step, search, starts, iterations,
        seed, generations, population, polish, max_time, rest_level, bounds, frozen,
        joint_weights, weight_velocity, weight_end, weight_effort, weight_grf, weight_com,
        out_dir, resume, overwrite, quiet):
    """Fit every unit's activation ramps to a measured motion of one or more joints.

    Inverse-dynamics start, then least squares (or --search global); the result is
    re-simulated with the reference solver. Ctrl-C or SIGTERM writes the best so far and a
    checkpoint; --resume continues.
    """
    _quiet_compiling(quiet)
    import signal

    import numpy as np

    from .batch.engine import signals_handled
    from .fitting import (
        FitProblem,
        ParameterSpace,
        SearchSettings,
        load_target,
    )
    from .fitting.fit import load_checkpoint
    from .fitting.outputs import CHECKPOINT_FILE, FIT_FILES, fit_and_write, summary_lines
    from .fitting.problem import held_field
    from .fitting.target import BUILTIN_TARGETS
    from .io.model_file import load_model

    out = _search_folder(out_dir, resume, overwrite, FIT_FILES, "fit")
    compiling_for(f"the model's checks ({model_path})")
    base = load_model(model_path)
    compiling_for(f"the fit's runs (IMEX, and Radau for the re-simulation) for "
                  f"{model_kind(base)}")
    if target_spec is None:
        own = model_path.removeprefix("builtin:")
        if not model_path.startswith("builtin:") or own not in BUILTIN_TARGETS:
            raise ModelError("--target", "required for a model file; allowed: a .csv, .mot "
                             "or .sto file, or builtin:" + "|".join(
                                 k for k in BUILTIN_TARGETS if k != "elbow-curl"))
        target_spec = "builtin:curl" if own == "elbow-curl" else model_path
    column_map = (columns[0] if len(columns) == 1 and "=" not in columns[0]
                  else _parse_pairs(columns, "--column", "elbow=r_elbow_flex"))
    if map_spec is not None:
        from .fitting.coordinate_map import default_map, map_file

        if isinstance(column_map, str):
            raise ModelError("--column", f"{column_map!r} with --map; allowed: JOINT=COLUMN")
        mapped = (map_file(map_spec) if map_spec.lower().endswith(".toml")
                  else default_map(map_spec, base))
        column_map = {**mapped, **column_map}
    try:
        target = load_target(target_spec, base, column_map, units)
    except ModelError as exc:
        raise _as_option(exc, {"column": "--column"}) from None
    if forces_path is not None:
        from .fitting.target import with_forces

        if target_spec.startswith("builtin:"):
            raise ModelError("--forces", "with a built-in motion, which has its own forces; "
                             "allowed: --forces with a --target file")
        target, lines = with_forces(base, target, forces_path, grf_cutoff, rezero,
                                    grf_components, lab_axes)
        for line in lines:
            click.echo(line, err=line.startswith("warning"))
    from .io.target_file import manifest_units

    table = units is None and Path(target_spec).suffix.lower() in (".csv", ".txt")
    declared = manifest_units(target_spec) if table else None
    if declared is not None:
        click.echo(f"note: {target_spec}: angles read in {declared}, as the manifest beside "
                   "it (written by torquesim) says", err=True)
    elif table:
        for joint, angle in zip(target.joints, target.angles, strict=True):
            if np.max(np.abs(np.degrees(angle))) <= math.pi:
                click.echo(f"warning: every target angle of {joint} is within ±3.2 degrees; "
                           "if the file is in radians, pass --angle-units rad", err=True)
    space = ParameterSpace.for_model(base, rest_level=rest_level)
    try:
        for name, (low, high) in _parse_assignments(bounds, "--bound", 2).items():
            space = space.with_bounds(name, low, high, base)
        for name, (value,) in _parse_assignments(frozen, "--freeze", 1).items():
            try:
                space = space.with_frozen(name, value)
            except ModelError:
                if not space.is_field(base, name):
                    raise
                base = held_field(base, name, value)  # a model field held, not fitted
    except ModelError as exc:
        raise _as_option(exc, {"freeze": "--freeze", "bound": "--bound",
                               "bounds": "--bound"}) from None
    weights = {j: v for j, (v,) in _parse_assignments(joint_weights, "--weight", 1).items()}
    settings = SearchSettings(search=search, seed=seed, starts=starts, iterations=iterations,
                              generations=generations, population_per_parameter=population,
                              polish_simulations=polish, max_time=max_time)
    try:
        problem = FitProblem(target, space, base, method, step, weight_velocity, weight_end,
                             weight_effort, weights, weight_grf, weight_com)
    except ModelError as exc:
        raise _as_option(exc, {"bounds": "--bound"}) from None
    checkpoint = out / CHECKPOINT_FILE
    state = None
    if resume:
        if not checkpoint.is_file():
            raise ModelError("--resume", f"no checkpoint {str(checkpoint)!r}; allowed: the "
                             "--out directory of an earlier fit")
        state = load_checkpoint(checkpoint, problem, settings)
    stop, request_stop = _stop_requests("the current simulations")
    with _kept_clean(out), signals_handled(request_stop, signal.SIGINT, signal.SIGTERM):
        reporter = Progress(quiet)
        problem, outcome, summary, files = fit_and_write(
            problem, settings, out, resume=state, progress=reporter.say,
            tick=lambda stage, done, total: reporter.step(done, total, stage),
            should_stop=lambda: bool(stop))
        reporter.close()
    click.echo("\n".join(summary_lines(summary)))
    return _search_written(outcome, stop, out_dir, (*files, CHECKPOINT_FILE), "fit")


@cli.command(short_help="Fit a unit's strength to dynamometer trials.")
@click.argument("trials", nargs=-1, type=click.Path())
@click.option("--model", "model_path", default="builtin:knee-extension", show_default=True,
              help="The model whose unit is fitted: a TOML file or one of " + preset_list()
              + ". Trial angles are its joint's angles (its zero and sign).")
@click.option("--unit", "unit_name", default=None,
              help="The unit fitted (e.g. knee_extensor). Default: the model's only unit, or "
              "the first unit whose direction matches the trials' torque.")
@click.option("--angle-units", "units", type=click.Choice(["deg", "rad"]), default=None,
              help="Units of angle and velocity in CSV trials. Default: deg (a .sto/.mot "
              "file's inDegrees decides).")
@click.option("--torque-sign", type=click.Choice(["joint", "unit"]), default="joint",
              show_default=True,
              help="joint: torque positive towards increasing joint angle; unit: positive "
              "in the unit's own direction (a magnitude, as many dynamometers export).")
@click.option("--passive", "passive_path", type=click.Path(dir_okay=False), default=None,
              help="A passive trial (relaxed limb moved through the range): its torque, "
              "fitted as A cos θ + B sin θ + C, is removed from every trial.")
@click.option("--gravity", "gravity", default=None, metavar="MOMENT@ANGLE",
              help="Instead of --passive: the gravity torque of limb and crank is "
              "MOMENT·cos(θ − ANGLE), N·m and degrees (e.g. -35@90).")
@click.option("--se-stiffness", type=click.FloatRange(0.0, 1e6, min_open=True), default=None,
              help="SE stiffness k (N·m/rad) for the CE angle θ_cc = θ ± T/k. Default: the "
              "unit's.")
@click.option("--limbs", type=click.IntRange(1, 4), default=1, show_default=True,
              help="Limbs the unit stands for (the squat jump's units are both legs: 2). The "
              "trials are one limb's: the fit uses the unit's SE stiffness / LIMBS and the "
              "model gets LIMBS times the fitted T0 and T_max.")
@click.option("--hold", "held", multiple=True, metavar="NAME=VALUE",
              help="Hold a parameter (SI units) instead of fitting it, e.g. "
              "max_velocity=22 from an independent estimate.")
@click.option("--above-weight", default="auto", show_default=True,
              help="Weight of samples above the fitted function (Forrester et al. 2011): a "
              "number in [1, 100], or auto (1 unless the residuals are one-sided, then 4).")
@click.option("--velocity-tolerance", type=click.FloatRange(0.0, 0.5, min_open=True),
              default=0.05, show_default=True,
              help="Constant-velocity phase: within this fraction of the set speed (and at "
              "least 2 deg/s).")
@click.option("--plateau", type=click.FloatRange(0.0, 1.0, min_open=True), default=0.95,
              show_default=True,
              help="Isometric trials: samples at or above this fraction of the peak torque.")
@click.option("--starts", type=click.IntRange(1, 200), default=8, show_default=True,
              help="Local searches (from the unit, the data and a Latin hypercube).")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=1, show_default=True,
              help="Seed of the Latin hypercube.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="strength-out",
              show_default=True, help="Output directory.")
@click.option("--overwrite", is_flag=True, help="Replace an earlier strength fit in --out.")
@click.option("--quiet", is_flag=True, help="No progress lines.")
def strength(trials, model_path, unit_name, units, torque_sign, passive_path, gravity,
             se_stiffness, limbs, held, above_weight, velocity_tolerance, plateau, starts, seed,
             out_dir, overwrite, quiet):
    """Fit a unit's maximum voluntary torque T(θ, ω) to isovelocity dynamometer trials.

    TRIALS are files (CSV, .sto or .mot), one per trial, with columns time (s), angle,
    velocity (optional) and torque (N·m): isometric trials at several angles, and
    concentric and eccentric isovelocity trials; a folder stands for every such file in it
    but the --passive one. Writes the model with the fitted unit, a table of the samples
    used, a figure and a summary (docs/strength.md).
    """
    _quiet_compiling(quiet)
    import time

    from .fitting.strength import PassiveTorque, StrengthSettings, fit_strength, for_limbs
    from .fitting.strength_outputs import (
        STRENGTH_FILES,
        strength_summary,
        summary_lines,
        write_strength,
    )
    from .io.dynamometer import read_trial
    from .io.model_file import load_model

    trials = _trial_files(trials, passive_path)
    if not trials:
        raise ModelError("TRIALS", "no trial files given; allowed: one or more .csv, .sto or "
                         ".mot files, or a folder of them (examples/dynamometer/ has some)")
    out = _search_folder(out_dir, False, overwrite, STRENGTH_FILES, "strength fit")
    model = load_model(model_path)
    names = [u.name for u in model.units]
    if unit_name is not None and unit_name not in names:
        raise ModelError("--unit", f"{unit_name!r}; allowed: {', '.join(names)}")
    if passive_path is not None and gravity is not None:
        raise ModelError("--gravity", "contradicts --passive; allowed: one of them")
    weight = above_weight
    if above_weight != "auto":
        try:
            weight = float(above_weight)
        except ValueError:
            raise ModelError("--above-weight", f"{above_weight!r}; allowed: auto or a number "
                             "in [1, 100]") from None
    hold = {name: value for name, (value,) in _parse_assignments(held, "--hold", 1).items()}
    unit = _strength_unit(model, unit_name, trials, units, torque_sign)
    try:
        settings = StrengthSettings(velocity_tolerance=velocity_tolerance, plateau=plateau,
                                    above_weight=weight,
                                    se_stiffness=(se_stiffness or unit.parameters.se_stiffness)
                                    / limbs, hold=hold, starts=starts, seed=seed)
    except ModelError as exc:
        raise _as_option(exc, {"above_weight": "--above-weight", "hold": "--hold"}) from None
    passive = PassiveTorque()
    if gravity is not None:
        moment, at, angle = gravity.partition("@")
        try:
            passive = PassiveTorque.given(float(moment), math.radians(float(angle)))
        except ValueError:
            raise ModelError("--gravity", f"{gravity!r}; allowed MOMENT@ANGLE in N·m and "
                             "degrees, e.g. -35@90") from None
    read = [read_trial(path, units, torque_sign, unit.direction) for path in trials]
    if passive_path is not None:
        passive = PassiveTorque.from_trial(read_trial(passive_path, units, torque_sign,
                                                      unit.direction, field="--passive"))
    say = (lambda message: None) if quiet else (lambda message: click.echo(message, err=True))
    started = time.perf_counter()
    try:
        fit = fit_strength(read, unit.parameters, unit.direction, settings, passive,
                           progress=say)
    except ModelError as exc:
        raise _as_option(exc, {"hold": "--hold"}) from None
    summary = strength_summary(fit, unit=unit.name, model=model_path,
                               trials=[Path(t).name for t in trials], passive=passive,
                               settings=settings, wall_time=time.perf_counter() - started,
                               limbs=limbs)
    if limbs > 1:
        fit = for_limbs(fit, limbs)
    out.mkdir(parents=True, exist_ok=True)
    files = write_strength(out, fit, model, unit.name, summary)
    click.echo("\n".join(summary_lines(summary)))
    click.echo(f"wrote {out_dir}/: {', '.join(files)}")
    return 0


def _trial_files(paths, passive_path) -> list[str]:
    """The trial files of ``paths``: each file as given, each folder's .csv, .sto and .mot
    files (sorted by name) but the passive trial's."""
    passive = Path(passive_path).resolve() if passive_path else None
    files = []
    for path in map(Path, paths):
        if path.is_dir():
            files += [str(p) for p in sorted(path.iterdir())
                      if p.suffix.lower() in (".csv", ".sto", ".mot") and p.resolve() != passive]
        else:
            files.append(str(path))
    return files


def _strength_unit(model, unit_name, trials, units, torque_sign):
    """The unit a strength fit is for: ``unit_name``, the model's only unit, or the first unit
    whose direction matches the sign of the first trial's largest torque (with
    --torque-sign joint)."""
    from .io.dynamometer import read_trial

    if unit_name is not None:
        return next(u for u in model.units if u.name == unit_name)
    if len(model.units) == 1:
        return model.units[0]
    if torque_sign == "unit":
        raise ModelError("--unit", "required with --torque-sign unit when the model has "
                         f"several units; allowed: {', '.join(u.name for u in model.units)}")
    import numpy as np

    first = read_trial(trials[0], units)
    sign = 1 if first.torque[int(np.argmax(np.abs(first.torque)))] > 0 else -1
    matching = [u for u in model.units if u.direction == sign]
    if not matching:
        raise ModelError("--unit", f"no unit of {model.name} pulls towards "
                         f"{'in' if sign > 0 else 'de'}creasing angle, as the torque of "
                         f"{Path(trials[0]).name} does; allowed: "
                         + ", ".join(u.name for u in model.units))
    return matching[0]


@cli.command(short_help="Optimise a performance: activation ramps for a goal.")
@click.option("--model", "model_path", default="builtin:elbow-curl", show_default=True,
              help="Starting model: a TOML file (e.g. a fit's fitted_model.toml) or "
                   f"a preset: {preset_list()}. Its activation "
                   "ramps (3 per unit) are the start of the search.")
@click.option("--maximise", "--maximize", "maximise", multiple=True, metavar="GOAL",
              help="A goal to maximise (repeatable): jump_height, com_speed_at_takeoff, "
                   "peak_speed:JOINT, speed_at:JOINT=ANGLE, time_to:JOINT=ANGLE, "
                   "final_angle:JOINT, effort; ANGLE in deg unless it ends in rad; W*GOAL "
                   "weights it (goals are combined in units of their start values).")
@click.option("--minimise", "--minimize", "minimise", multiple=True, metavar="GOAL",
              help="A goal to minimise (repeatable), e.g. time_to:elbow=90deg or '0.1*effort' "
                   "(quoted for the shell).")
@click.option("--method", type=click.Choice(FIT_METHODS), default=None,
              help="Technique of every candidate's run (explicit RK4 ones need a small step; "
                   "runs beyond its stability limit fail). Default: the cheapest technique "
                   "and step whose run of the start meets --accuracy (imex, or on a body on "
                   "the ground imex or imex-ros2), said in the output; imex with a --step.")
@click.option("--step", type=TIME, default=None,
              help="Fixed step (s; ms/us suffixes). Default: the cheapest that meets "
                   "--accuracy (of --method, or of the technique chosen).")
@click.option("--accuracy", type=float, default=0.05, show_default=True,
              help="Max angle error (deg) the default technique and step must meet on the "
                   "start's run (estimated by step doubling, as simulate's check).")
@click.option("--duration", type=TIME, default=None,
              help="Simulate this long instead of the model's duration (s).")
@click.option("--free", "free", multiple=True, metavar="PATH",
              help="What may change (repeatable): a unit (elbow_flexor, elbow.flexor), "
                   "UNIT.rampK or UNIT.rampK.FIELD, or a model field given a --bound; "
                   "everything else is frozen. Default: every unit's ramps and every model "
                   "field given a --bound.")
@click.option("--freeze", "frozen", multiple=True, metavar="PATH[=VALUE]",
              help="Hold a unit, a ramp or a parameter (repeatable) at its start value or at "
                   "VALUE, e.g. elbow_extensor or elbow_flexor.ramp1.level=0.6; a model "
                   "field's path at VALUE (SI) sets it in the start, which gains are measured "
                   "from.")
@click.option("--bound", "bounds", multiple=True, metavar="PATH=LOW,HIGH",
              help="Bounds replacing the window (repeatable; s for delays and durations), "
                   "e.g. elbow_flexor.ramp1.level=0,1; they must contain the start value. A "
                   "model field's path (SI) searches that field too: knee.initial_angle=1,2, "
                   "gastrocnemius.se_stiffness=1500,4000 (see torquesim model NAME --paths).")
@click.option("--window-delay", type=TIME, default=0.05, show_default=True,
              help="Every delay may move ± this (s) from the start's.")
@click.option("--window-duration", type=click.FloatRange(0.0, 0.99), default=0.3,
              show_default=True, help="Every ramp duration may move ± this fraction.")
@click.option("--window-level", type=click.FloatRange(0.0, 10.0), default=0.3,
              show_default=True,
              help="Every level may move ± this fraction (at least ± 0.05 activation).")
@click.option("--constrain", "constrain", multiple=True, metavar="GOAL=LOW..HIGH",
              help="Hold a goal's value within bounds (repeatable; either bound may be left "
                   "out), in its unit (m, m/s, s; degrees and deg/s for angles and angular "
                   "speeds), e.g. com_speed_x_at_takeoff=-0.1..0.1 or final_angle:elbow=..150. "
                   "A candidate outside is infeasible.")
@click.option("--endstop-depth", type=click.FloatRange(0.0, 20.0), default=0.0,
              show_default=True,
              help="How far a run may go past an end stop, in end-stop angle scales (0: not "
                   "past the stop angle, so an optimum does not lean on passive stop torque).")
@click.option("--robust", type=click.IntRange(0, 1000), default=0, show_default=True,
              help="Score each candidate on its run and this many copies with random onset "
                   "errors on every ramp (0: the plain optimum).")
@click.option("--timing-error", type=TIME, default=0.01, show_default=True,
              help="Largest onset error of the robust copies (s; uniform in ±).")
@click.option("--robust-mode", type=click.Choice(["worst", "mean"]), default="worst",
              show_default=True, help="Robust score: the worst or the mean over the copies.")
@click.option("--generations", type=click.IntRange(1, 100_000), default=60, show_default=True,
              help="CMA-ES generations.")
@click.option("--population", type=click.IntRange(4, 10_000), default=None,
              help="Candidates per generation. Default: 4 + 3·ln(free parameters).")
@click.option("--sigma", type=click.FloatRange(0.0, 1.0, min_open=True), default=0.2,
              show_default=True, help="CMA-ES's initial step, as a fraction of each bound.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=1, show_default=True,
              help="Random seed: the same seed gives the same optimum.")
@click.option("--workers", type=click.IntRange(1, 1024), default=None,
              help="Score each generation on a local Dask cluster of N worker processes "
                   "(default: this process's compiled threads).")
@click.option("--scheduler", default=None, metavar="tcp://HOST:PORT",
              help="Score each generation on a running Dask scheduler's workers (they need "
                   "torquesim installed; no shared folder).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="optimise-out",
              show_default=True, help="Directory for the optimised model, motion, figure, "
                                      "page, summary and checkpoint.")
@click.option("--resume", is_flag=True, help="Continue from OUT/optimise_checkpoint.npz.")
@click.option("--overwrite", is_flag=True,
              help="Start again in an --out directory that holds an earlier optimisation.")
@click.option("--quiet", is_flag=True, help="No progress bar or progress lines.")
def optimise(model_path, maximise, minimise, method, step, accuracy, duration, free, frozen,
             bounds, window_delay, window_duration, window_level, constrain, endstop_depth,
             robust, timing_error, robust_mode, generations, population, sigma, seed, workers,
             scheduler, out_dir, resume, overwrite, quiet):
    """Optimise the activation ramps of a model for one or more goals.

    Every ramp may move within a window around the starting model's (the optimum stays a
    technique the performer could use); CMA-ES searches, its population simulated in
    parallel; start and optimum are re-simulated with the reference solver and compared.
    Ctrl-C or SIGTERM writes the best so far and a checkpoint; --resume continues.
    """
    _quiet_compiling(quiet)
    import signal

    from .batch.engine import signals_handled
    from .io.model_file import load_model
    from .optimisation import (
        OptimiseProblem,
        OptimiseSettings,
        Window,
        constraints_of,
        goals_of,
    )
    from .optimisation.outputs import (
        CHECKPOINT_FILE,
        OPTIMISE_FILES,
        optimise_and_write,
        summary_lines,
    )
    from .optimisation.search import load_checkpoint

    out = _search_folder(out_dir, resume, overwrite, OPTIMISE_FILES, "optimisation")
    if not maximise and not minimise:
        raise ModelError("--maximise", "no goal given; allowed: --maximise GOAL or "
                         "--minimise GOAL, e.g. --minimise time_to:elbow=90deg")
    compiling_for(f"the model's checks ({model_path})")
    model = load_model(model_path)
    compiling_for(f"the optimiser's runs ({method or 'the techniques it chooses from'}, and "
                  f"Radau for the check) for {model_kind(model)}")
    if duration is not None:
        from .errors import check_range

        model = model.replace(duration=check_range("--duration", duration, 0.0,
                                                    low_open=True, unit="s"))
    try:
        goals = goals_of(model, maximise, minimise)
        constraints = constraints_of(model, constrain)
    except ModelError as exc:
        raise _as_option(exc, OPTIMISE_OPTIONS) from None
    freeze = {}
    for text in frozen:
        name, eq, value = text.partition("=")
        try:
            freeze[name.strip()] = float(value) if eq else None
        except ValueError:
            raise ModelError("--freeze", f"{text!r}: allowed PATH or PATH=VALUE, e.g. "
                             "elbow_flexor.ramp1.level=0.6") from None
    from .errors import check_range

    check_range("--window-delay", window_delay, 0.0, 10.0, unit="s")
    check_range("--timing-error", timing_error, 0.0, 1.0, unit="s")
    window = Window(delay=window_delay, duration=window_duration, level=window_level)
    limits = dict(_parse_assignments(bounds, "--bound", 2))
    settings = OptimiseSettings(seed=seed, generations=generations, population=population,
                                sigma=sigma)
    checkpoint = out / CHECKPOINT_FILE
    if resume and not checkpoint.is_file():
        raise ModelError("--resume", f"no checkpoint {str(checkpoint)!r}; allowed: the --out "
                         "directory of an earlier optimisation")
    stop, request_stop = _stop_requests("the current generation")

    from contextlib import nullcontext

    from .batch.engine import connect
    from .optimisation.distributed import DaskScorer

    engine = (connect(workers=workers, scheduler=scheduler)
              if workers is not None or scheduler is not None else nullcontext())
    with _kept_clean(out), engine as client:
        # The cluster's workers are forked before this process runs compiled parallel code
        # (the problem simulates its start): forking after OpenMP is unsafe.
        try:
            problem = OptimiseProblem(model, goals, method, step, window, tuple(free), freeze,
                                      limits, robust, timing_error, robust_mode,
                                      constraints=constraints, endstop_depth=endstop_depth,
                                      accuracy=_tolerance_rad(accuracy, "--accuracy"))
        except ModelError as exc:
            raise _as_option(exc, OPTIMISE_OPTIONS) from None
        state = None
        if resume:
            state = load_checkpoint(checkpoint, problem, settings)
        with signals_handled(request_stop, signal.SIGINT, signal.SIGTERM):
            reporter = Progress(quiet)
            if problem.choice is not None:
                reporter.say(problem.choice.describe())
            scorer = None if client is None else DaskScorer(client, problem)
            where = "this process" if scorer is None else f"{scorer.workers} Dask workers"
            reporter.say(f"optimising {len(problem.space.free)} parameters of {model.name} "
                         f"({problem.method} at {problem.step * 1e3:.4g} ms, "
                         f"{1 + problem.robust} run(s) per candidate, on {where})")
            outcome, summary, files = optimise_and_write(
                problem, settings, out, resume=state, progress=reporter.say,
                tick=lambda done, total: reporter.step(done, total, "generations"),
                should_stop=lambda: bool(stop),
                evaluate=scorer)
            reporter.close()
    click.echo("\n".join(summary_lines(summary, problem)))
    return _search_written(outcome, stop, out_dir, (*files, CHECKPOINT_FILE), "search")


def _stop_requests(what: str):
    """(stop, handler): a handler for SIGINT and SIGTERM that asks a search to stop, the
    signals it heard appended to ``stop``: the search finishes ``what``, then writes the best
    so far. Installed until the outputs are written, so that an interrupt while they are
    written only sets the flag: the files always come from the same parameters (each is
    replaced atomically)."""
    stop = []

    def request_stop(signum, _frame):
        stop.append(signum)
        click.echo(f"stopping: finishing {what}, then writing the best so far", err=True)

    return stop, request_stop


@contextmanager
def _kept_clean(out: Path):
    """The --out folder ``out`` removed again when a ModelError ends the command inside and
    this command created it, empty."""
    created = not out.exists()
    try:
        yield
    except ModelError:
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise


def _search_written(outcome, stop, out_dir: str, files, what: str) -> int:
    """The last lines of a fit or an optimisation (``what``), which wrote ``files`` into
    ``out_dir``, and its exit code: 130 when ``outcome`` was interrupted (its best so far
    written), else 0."""
    click.echo(f"wrote {out_dir}/: {', '.join(files)}")
    if stop and not outcome.interrupted:
        click.echo(f"the {what} had finished when the stop request came: its outputs are "
                   "complete", err=True)
    if outcome.interrupted:
        click.echo(f"interrupted: best so far written; continue with --resume --out {out_dir}",
                   err=True)
        return 130
    return 0


@cli.group(short_help="Many fits or a parameter sweep, on Dask.")
def batch():
    """Many runs on Dask distributed: batch fits and parameter sweeps.

    Default engine: a local cluster with one worker process per core (one thread each);
    --workers N to choose, --scheduler tcp://HOST:PORT for an existing cluster (its workers
    need torquesim installed and, for fits, the same file system).
    """


def _engine_options(fn):
    fn = click.option("--workers", type=click.IntRange(1, 1024), default=None,
                      help="Local worker processes (default: one per core).")(fn)
    fn = click.option("--scheduler", default=None, metavar="tcp://HOST:PORT",
                      help="Use a running Dask scheduler instead of a local cluster.")(fn)
    return click.option("--quiet", is_flag=True, help="No progress bar or lines.")(fn)


def _interruptible():
    """SIGINT and SIGTERM raise KeyboardInterrupt in this process while the batch runs, even
    when it was started with SIGINT ignored (a background job of a script): the batch then
    cancels, stops its tasks, writes what finished and exits 130."""
    import signal

    from .batch.engine import signals_handled

    def interrupt(_signum, _frame):
        raise KeyboardInterrupt

    return signals_handled(interrupt, signal.SIGINT, signal.SIGTERM)


def _batch_progress(quiet: bool, label: str):
    """A `Progress` and the ``progress(done, total)`` callback of batch work: the
    bar on a terminal, a line per finished task otherwise."""
    reporter = Progress(quiet)

    def progress(done: int, total: int) -> None:
        reporter.step(done, total, label)
        if not reporter.bars:
            reporter.say(f"{label} {done}/{total}")

    return reporter, progress


@batch.command("fit", short_help="Fit many targets, one folder each.")
@click.argument("targets", nargs=-1)
@click.option("--manifest", type=click.Path(dir_okay=False),
              help="CSV with columns target,model,column (model and column optional) "
                   "instead of, or beside, TARGETS.")
@click.option("--model", "model_path", default="builtin:elbow-curl", show_default=True,
              help="Model for every target without one in the manifest: a TOML file or a "
                   f"preset: {preset_list()}.")
@_search_options
@click.option("--weight-effort", type=click.FloatRange(0.0, 1e6), default=0.0,
              show_default=True, help="Weight (deg² per activation²) of the effort term, as "
                                      "in `fit`.")
@click.option("--angle-units", "--units", "units", type=click.Choice(["deg", "rad"]),
              help="Units of CSV targets (default deg; .mot/.sto: inDegrees).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="batch-out",
              show_default=True, help="One folder per target, batch.csv and batch.html.")
@_engine_options
def batch_fit(targets, manifest, model_path, method, step, search, starts, iterations, seed,
              weight_effort, units, out_dir, workers, scheduler, quiet):
    """Fit every TARGET (files, globs or builtin:NAME), each into OUT/NAME/.

    Finished fits are skipped when the command is run again (same target, model and
    settings); unfinished ones resume from their checkpoints. Exit code 1 if any target
    failed (its row in batch.csv says why), 130 on Ctrl-C with what finished on disk.
    """
    _quiet_compiling(quiet)
    _check_out_folder(Path(out_dir))
    from .batch import fit_many

    reporter, progress = _batch_progress(quiet, "fits")
    try:
        with _interruptible():
            table = fit_many(targets, out=out_dir, model=model_path, manifest=manifest,
                             method=method, step=step, search=search, seed=seed,
                             starts=starts, iterations=iterations, weight_effort=weight_effort,
                             units=units, workers=workers, scheduler=scheduler,
                             progress=progress)
    except KeyboardInterrupt:
        reporter.close()
        click.echo(f"interrupted: finished fits are in {out_dir}/batch.csv; run the same "
                   "command again to continue", err=True)
        return 130
    reporter.close()
    failed = table[table["status"] == "failed"]
    click.echo(f"{len(table) - len(failed)} of {len(table)} fits done; wrote "
               f"{out_dir}/batch.csv, batch.html")
    for _, row in failed.iterrows():
        click.echo(f"failed: {row['name']}: {row['error']}", err=True)
    return 1 if len(failed) else 0


@batch.command("sweep", short_help="Simulate over parameter distributions.")
@click.option("--model", "model_path", default="builtin:elbow-curl", show_default=True,
              help=f"Model: a TOML file or a preset: {preset_list()}.")
@click.option("--vary", multiple=True, required=True, metavar="PATH=KIND(...)",
              help="A model field and its distribution (repeatable): uniform(LOW,HIGH), "
                   "normal(MEAN,SD), lognormal(MEDIAN,SIGMA) or grid(LOW,HIGH,N); PATH as in "
                   "the model file, e.g. elbow_flexor.se_stiffness (or flexor.se_stiffness "
                   "on the elbow), forearm_hand.dumbbell.mass, elbow.initial_angle.")
@click.option("--samples", type=click.IntRange(1, 10_000_000), default=1000,
              show_default=True, help="Monte Carlo samples (crossed with any grids).")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=1, show_default=True,
              help="Random seed of the samples (drawn in the client: the same table whatever "
                   "the workers).")
@click.option("--sobol", is_flag=True, help="Scrambled Sobol' points instead of random.")
@click.option("--method", type=click.Choice(FIT_METHODS), default=None,
              help="Technique of every sample (as in `simulate`). Default: the cheapest "
                   "technique and step whose run of the model as given is within half the "
                   "--tolerance (imex, or on a body on the ground imex or imex-ros2), said in "
                   "the output; imex with a --step.")
@click.option("--step", type=TIME, default=None,
              help="Fixed step of every sample (s; ms/us suffixes); must divide the duration. "
                   "Default: the cheapest that meets half the --tolerance (of --method, or of "
                   "the technique chosen).")
@click.option("--chunk", type=click.IntRange(1, 1_000_000), default=None,
              help="Samples per Dask task (default: an even split giving every worker at "
                   "least 4 tasks, at most 1000 samples each).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="sweep-out",
              show_default=True, help="Directory for sweep.csv, the percentile bands, the rank "
                                      "correlations, sweep.html and the finished chunks.")
@click.option("--tolerance", type=float, default=0.5, show_default=True,
              help="Each sample's max angle error is estimated (against a run at twice the "
                   "step, half a run's work); a sample above this many degrees is run again "
                   "at half the step (up to 5 times), and marked inaccurate if it still is.")
@click.option("--accept-inaccurate", is_flag=True,
              help="Exit 0 even when some samples are inaccurate or unstable.")
@click.option("--overwrite", is_flag=True, help="Replace another sweep held in --out.")
@_engine_options
def batch_sweep(model_path, vary, samples, seed, sobol, method, step, chunk, out_dir,
                tolerance, accept_inaccurate, overwrite, workers, scheduler, quiet):
    """Simulate the model over parameter distributions; write sweep.csv (one row per
    sample), percentile bands (sweep.png, sweep_percentiles.csv), rank correlations and
    sweep.html. Finished chunks are kept in OUT/chunks and skipped on a rerun."""
    _quiet_compiling(quiet)
    _check_out_folder(Path(out_dir))
    from .batch import sweep
    from .batch.sweep import MAX_REFINEMENTS

    reporter, progress = _batch_progress(quiet, "chunks")
    try:
        with _interruptible():
            table, _ = sweep(model_path, vary, samples=samples, seed=seed, sobol=sobol,
                             method=method, step=step, out=out_dir, chunk=chunk,
                             workers=workers, scheduler=scheduler, progress=progress,
                             overwrite=overwrite,
                             tolerance=_tolerance_rad(tolerance, "--tolerance"))
    except KeyboardInterrupt:
        reporter.close()
        click.echo(f"interrupted: finished chunks are in {out_dir}/chunks; run the same "
                   "command again to continue", err=True)
        return 130
    reporter.close()
    if table.attrs.get("choice"):
        click.echo(table.attrs["choice"])
    counts = table["accuracy"].value_counts().to_dict()
    failed = counts.get("failed", 0)
    doubtful = table[table["accuracy"].isin(["inaccurate", "unstable"])]
    step = table.attrs["step_s"]
    refined = int(((table["step_s"] < step * (1 - 1e-9)) & (table["accuracy"] == "ok")).sum())
    click.echo(f"{len(table)} samples: {counts.get('ok', 0)} accurate (estimated error within "
               f"{tolerance:g}°; {refined} of them re-run at a smaller step, as the step_s "
               f"column gives), {counts.get('inaccurate', 0)} inaccurate and "
               f"{counts.get('unstable', 0)} beyond the stability limit even at "
               f"{step / 2**MAX_REFINEMENTS * 1e3:.3g} ms, {failed} failed; wrote "
               f"{out_dir}/sweep.csv, sweep.png, sweep_percentiles.csv, rank_correlations.csv, "
               "sweep.html")
    if len(doubtful) and not accept_inaccurate:
        first = doubtful.iloc[0]
        click.echo(f"error: {len(doubtful)} of {len(table)} samples cannot be made accurate "
                   f"by halving the step {MAX_REFINEMENTS} times (samples "
                   f"{', '.join(str(int(k)) for k in doubtful['sample'][:10])}"
                   f"{', …' if len(doubtful) > 10 else ''}; sample {int(first['sample'])}: "
                   f"{first['error'].split(' Also: ')[0]}); use --method imex or a larger "
                   "--tolerance, or --accept-inaccurate to accept them", err=True)
        return 1
    return 1 if failed else 0


#: The Python fields of an optimisation and the options that set them.
OPTIMISE_OPTIONS = {"maximise": "--maximise", "minimise": "--minimise",
                    "constrain": "--constrain", "endstop_depth": "--endstop-depth",
                    "free": "--free",
                    "frozen": "--freeze", "freeze": "--freeze", "bounds": "--bound",
                    "timing_error": "--timing-error", "robust": "--robust", "step": "--step",
                    "method": "--method", "accuracy": "--accuracy",
                    "window.delay": "--window-delay",
                    "window.duration": "--window-duration", "window.level": "--window-level"}


def _as_option(exc: ModelError, options: dict[str, str]) -> ModelError:
    """``exc`` naming the command-line option of its field (``bounds.X`` → ``--bound X``)."""
    head, dot, rest = exc.field.partition(".")
    if exc.field in options:
        return ModelError(options[exc.field], exc.reason)
    if head in options and dot:
        return ModelError(f"{options[head]} {rest}", exc.reason)
    return exc


def _tolerance_rad(degrees: float, option: str) -> float:
    """A tolerance option in degrees, checked, in radians."""
    from .errors import check_range

    return math.radians(check_range(option, degrees, 0.0, 180.0, low_open=True, unit="deg"))


def _explicit_defaults(command: click.Command) -> None:
    """Options without a default get their real one (None, False for a flag, () for a
    repeatable option) instead of click's internal sentinel, so that help pages and the
    generated CLI reference show what a user gets."""
    # made once per command, then kept: with the group's option names (-h, --help)
    help_option = command.get_help_option(click.Context(command, **CONTEXT))
    for param in [*command.params, *([help_option] if help_option else [])]:
        if type(param.default).__name__ == "Sentinel":
            flag = isinstance(param, click.Option) and param.is_flag
            many = param.multiple or param.nargs == -1
            param.default = False if flag else (() if many else None)
    for sub in getattr(command, "commands", {}).values():
        _explicit_defaults(sub)


_explicit_defaults(cli)


def main(argv=None) -> int:
    """Entry point: one-line errors, exit code 2 for bad input, 1 for a failed run."""
    try:
        with CompileReporter() as reporter:
            code = cli.main(args=argv, prog_name="torquesim", standalone_mode=False,
                            obj=reporter)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        return 130
    except click.ClickException as exc:
        click.echo(f"error: {exc.format_message()}".replace("\n", " "), err=True)
        return 2
    except ModelError as exc:
        click.echo(f"error: {exc}", err=True)
        return 2
    except SimulationError as exc:
        click.echo(f"error: {exc}", err=True)
        return 1
    except OSError as exc:  # a path the command could not create or write
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"error: {where}{exc.strerror or exc}", err=True)
        return 2
    return code if isinstance(code, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
