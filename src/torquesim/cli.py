"""Command-line interface: ``torquesim simulate``, ``torquesim model``."""

from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import click

from .errors import ModelError, SimulationError

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


def _check_output(path: str | None, suffixes, option: str) -> None:
    if path is None:
        return
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise ModelError(option, f"{path!r}: unknown extension; allowed {', '.join(suffixes)}")
    if not (p.parent if str(p.parent) else Path(".")).is_dir():
        raise ModelError(option, f"directory {str(p.parent)!r} does not exist")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="torquesim")
def cli():
    """torquesim: torque-driven simulation of an elbow dumbbell curl.

    Compares the partitioned and monolithic solution of the body and muscle equations.
    SI units throughout; angles in radians in files, degrees in summaries.
    """


@cli.command()
@click.option("--model", "model_path", type=click.Path(dir_okay=False),
              help="Model TOML file (default: the built-in 5 kg curl; see 'torquesim model').")
@click.option("--method", type=click.Choice(["monolithic", "partitioned", "imex", "reference"]),
              default="monolithic", show_default=True,
              help="monolithic: one RK4 on all equations; partitioned: each part its own RK4, "
                   "zero-order hold exchange; imex: body explicit RK4, muscles implicit "
                   "(L-stable SDIRK2), stable at large steps; reference: SciPy Radau, "
                   "rtol 1e-10.")
@click.option("--step", type=TIME, default="0.1ms", show_default=True,
              help="Fixed step of the RK4 methods (s; suffixes ms/us accepted). Must divide "
                   "the duration. Output grid of 'reference' is 1 ms.")
@click.option("--duration", type=TIME, default=None, help="Override the model's duration (s).")
@click.option("--out", "out_path", type=click.Path(dir_okay=False),
              help="Write the trajectory: .csv or OpenSim .sto/.mot (rad, SI), with a "
                   ".manifest.json beside it.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Write a figure of angle, torques and activations (.png, .pdf, .svg).")
def simulate(model_path, method, step, duration, out_path, plot_path):
    """Simulate the model and print a summary (or write --out / --plot)."""
    from .io.model_file import load_model
    from .model import default_model
    from .solvers import simulate as run

    _check_output(out_path, (".csv", ".sto", ".mot"), "--out")
    _check_output(plot_path, PLOT_SUFFIXES, "--plot")
    model = load_model(model_path) if model_path else default_model()
    result = run(model, method, step, duration=duration)
    if result.stability is not None and result.stability.exceeded:
        click.echo(f"warning: {result.stability.message()}", err=True)
    if out_path:
        result.save(out_path)
    if plot_path:
        from .plots import plot_result, save_figure

        save_figure(plot_result(result), plot_path)
    peak, t_peak = result.peak()
    lines = [
        f"method        {result.method}"
        + (f", step {result.step * 1e3:g} ms" if result.step else
           f", rtol {result.settings['rtol']:g}"),
        f"duration      {result.time[-1]:g} s",
        f"peak angle    {math.degrees(peak):.4f} deg at t = {t_peak:.4f} s",
        f"final angle   {math.degrees(result.theta[-1]):.4f} deg",
        f"steps         {result.cost.steps if result.cost.steps >= 0 else 'adaptive'}",
        f"rhs evals     body {result.cost.rhs_body}, muscle {result.cost.rhs_muscle}",
        f"wall time     {result.cost.wall_time * 1e3:.1f} ms",
    ]
    report = result.stability
    if report is not None:
        limit = ("muscles implicit, no step limit from tau" if math.isinf(report.limit)
                 else f"largest safe step {report.largest_safe_step * 1e3:.3g} ms")
        lines.append(f"stability     max step/tau {report.max_step_ratio:.3g} "
                     f"({report.unit}); {limit}")
    if out_path:
        lines.append(f"wrote         {out_path}")
    if plot_path:
        lines.append(f"wrote         {plot_path}")
    click.echo("\n".join(lines))


@cli.command()
@click.option("--out", "out_path", type=click.Path(dir_okay=False), required=True,
              help="Where to write the model TOML.")
@click.option("--model", "model_path", type=click.Path(dir_okay=False),
              help="Start from this model file instead of the built-in default.")
def model(out_path, model_path):
    """Write the default model (or a checked copy of --model) as an editable TOML file."""
    from .io.model_file import load_model, save_model
    from .model import default_model

    _check_output(out_path, (".toml",), "--out")
    save_model(load_model(model_path) if model_path else default_model(), out_path)
    click.echo(f"wrote {out_path}")


def _parse_steps(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(x) * 1e-3 for x in text.split(",") if x.strip())
    except ValueError:
        raise ModelError("--steps", f"{text!r}: allowed a comma-separated list of steps in "
                         "ms, e.g. 1,0.5,0.1") from None
    if not values:
        raise ModelError("--steps", "allowed a non-empty comma-separated list of steps in ms")
    return values


@cli.command()
@click.option("--model", "model_path", type=click.Path(dir_okay=False),
              help="Model TOML file (default: the built-in curl).")
@click.option("--steps", default="20,10,5,2,1,0.5,0.2,0.1,0.05", show_default=True,
              help="Fixed steps to try, in ms, comma-separated; each must divide the duration.")
@click.option("--repeats", type=click.IntRange(1, 50), default=3, show_default=True,
              help="Runs per setting; the median wall time is reported.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="compare-out",
              show_default=True, help="Directory for results.csv, figures, report.html.")
def compare(model_path, steps, repeats, out_dir):
    """Every technique over a range of steps against the reference: accuracy, order,
    stability and cost, and the verdict."""
    from .io.model_file import load_model
    from .model import default_model
    from .solvers.simulate import step_count
    from .study.compare import verdict, verdict_sentences
    from .study.outputs import write_study

    model = load_model(model_path) if model_path else default_model()
    values = _parse_steps(steps)
    for h in values:
        step_count(model.duration, h, "--steps")

    def progress(message):
        click.echo(message, err=True)

    rows, _, smooth = write_study(out_dir, model, steps=values, repeats=repeats,
                                  progress=progress, model_source=model_path or "builtin")
    names = list(dict.fromkeys(r["technique"] for r in rows))
    click.echo("\n".join(verdict_sentences(verdict(rows), names)))
    click.echo(f"wrote {out_dir}/results.csv, report.html, convergence.png, "
               "work_precision.png, time_constants.png, manifest.json")


def main(argv=None) -> int:
    """Entry point: one-line errors, exit code 2 for bad input, 1 for a failed run."""
    try:
        cli.main(args=argv, prog_name="torquesim", standalone_mode=False)
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
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
