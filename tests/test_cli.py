"""The command line: summaries, files, one-line errors with exit code 2."""

import subprocess
import sys

import numpy as np
import pytest

import torquesim as ts
from torquesim.cli import main


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_simulate_prints_a_summary(capsys):
    code, out, err = run(["simulate", "--duration", "1.5"], capsys)
    assert code == 0
    assert "elbow_flexion min 10.0000 deg at t = 0.0000 s, peak 138.7" in out
    assert "steps         15000" in out
    # the stability line: τ_min and the limit it sets, each named (0.2 printed
    # "limit 2.785 tau_min = 0.411 ms", which reads as τ_min = 0.411 ms)
    assert "τ_min 0.148 ms; RK4 limit 2.785·τ_min = 0.411 ms" in out
    # nothing else on stderr (on an empty Numba cache, the compile notes)
    assert [line for line in err.splitlines() if not line.startswith(("compiling the "
            "integrators", "still compiling"))] == []


def test_simulate_writes_table_and_plot(tmp_path, capsys):
    out_file, png = tmp_path / "curl.sto", tmp_path / "curl.png"
    code, out, _ = run(["simulate", "--method", "partitioned", "--step", "0.2ms",
                        "--duration", "0.5", "--out", str(out_file), "--plot", str(png)],
                       capsys)
    assert code == 0
    table = ts.read_table(out_file)
    assert table["time"][-1] == pytest.approx(0.5) and table["time"].size == 2501
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_reference_writes_the_1ms_grid(tmp_path, capsys):
    out_file = tmp_path / "ref.csv"
    code, *_ = run(["simulate", "--method", "reference", "--duration", "0.3",
                    "--out", str(out_file)], capsys)
    assert code == 0
    assert ts.read_table(out_file)["time"].size == 301


def test_large_step_warns(capsys):
    code, _, err = run(["simulate", "--step", "1ms"], capsys)
    assert code == 0 and "warning" in err and "extensor" in err


@pytest.mark.parametrize("argv, needle", [
    (["simulate", "--step", "0.7ms"], "step"),
    (["simulate", "--step", "abc"], "not a time"),
    (["simulate", "--duration", "-1"], "duration"),
    (["simulate", "--method", "euler"], "euler"),
    (["simulate", "--model", "missing.toml"], "cannot read"),
    (["simulate", "--out", "x.xlsx"], "--out"),
    (["simulate", "--out", "no/such/dir/x.csv"], "does not exist"),
])
def test_bad_input_is_one_line_exit_2_no_file(tmp_path, monkeypatch, capsys, argv, needle):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(argv + ["--out", "run.csv"] if "--out" not in argv else argv, capsys)
    assert code == 2
    assert err.startswith("error:") and needle in err and err.count("\n") == 1
    assert "Traceback" not in err
    assert not (tmp_path / "run.csv").exists()


def test_bad_model_file_names_the_key(tmp_path, capsys):
    bad = tmp_path / "m.toml"
    assert run(["model", "--out", str(bad)], capsys)[0] == 0
    text = bad.read_text()
    assert 'name = "dumbbell", mass = 5.0,' in text
    bad.write_text(text.replace('"dumbbell", mass = 5.0,', '"dumbbell", mass = -5.0,'))
    code, _, err = run(["simulate", "--model", str(bad), "--out", str(tmp_path / "o.csv")],
                       capsys)
    assert code == 2 and "segments[0].loads[0].mass" in err and "[0, 1000] kg" in err
    assert not (tmp_path / "o.csv").exists()


def test_blow_up_exits_1_without_output(tmp_path, capsys):
    code, _, err = run(["simulate", "--step", "0.1", "--out", str(tmp_path / "o.csv")], capsys)
    assert code == 1 and "use a step ≤" in err and "checked" in err
    assert not (tmp_path / "o.csv").exists()


def test_installed_entry_point(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "torquesim.cli", "simulate", "--step", "0.7ms",
                           "--duration", "0.9"], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2 and proc.stderr.startswith("error: step")


@pytest.mark.parametrize("name", ["knee-extension", "arm-raise"])
def test_presets_simulate_with_columns_named_after_joints_and_units(tmp_path, capsys, name):
    path = tmp_path / f"{name}.toml"
    assert run(["model", name, "--out", str(path)], capsys)[0] == 0
    chain = ts.load_model(path)
    assert chain == ts.load_model(f"builtin:{name}")
    out_file, png = tmp_path / "run.mot", tmp_path / "run.png"
    code, out, err = run(["simulate", "--model", str(path), "--method", "imex", "--step",
                          "2ms", "--out", str(out_file), "--plot", str(png)], capsys)
    assert code == 0, err
    table = ts.read_table(out_file)
    for joint in chain.joints:
        assert joint.coordinate in table and f"torque_net_{joint.name}" in table
        assert joint.coordinate in out  # one summary line per joint
    for unit in chain.units:
        assert f"torque_{unit.name}" in table and f"activation_{unit.name}" in table
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_fit_of_a_model_file_needs_a_target(tmp_path, capsys):
    """A preset brings its own built-in motion; a model file does not."""
    model = tmp_path / "arm.toml"
    assert run(["model", "builtin:arm-raise", "--out", str(model)], capsys)[0] == 0
    code, _, err = run(["fit", "--model", str(model), "--out", str(tmp_path / "f")], capsys)
    assert code == 2 and "--target" in err and err.count("\n") == 1
    assert not (tmp_path / "f").exists()
    code, _, err = run(["fit", "--model", str(model), "--target", "builtin:knee-extension",
                        "--out", str(tmp_path / "f")], capsys)
    assert code == 2 and "does not have" in err and not (tmp_path / "f").exists()


def test_unknown_preset_lists_the_allowed_ones(capsys):
    code, _, err = run(["simulate", "--model", "builtin:squat"], capsys)
    assert code == 2 and "builtin:arm-raise" in err


def test_a_cold_start_is_announced_when_compiling_begins():
    """Numba compiling in a command: one line says so when it begins (listening to Numba's
    compile events, which a cache hit does not fire), once per command; with every kernel on
    disk nothing is said."""
    from numba import njit

    from torquesim.cli import CompileReporter

    lines = []
    with CompileReporter(echo=lines.append) as reporter:
        reporter.listen()
        COMPILING_NOTICE = reporter.notice

        @njit
        def fresh(x):  # not cached: calling it compiles
            return x + 1.0

        fresh(1.0)
        assert lines == [COMPILING_NOTICE]

        @njit
        def another(x):
            return x * 2.0

        another(1.0)
        assert lines == [COMPILING_NOTICE]  # once per command
    fresh(2)  # a new signature compiles, but the reporter is closed
    assert lines == [COMPILING_NOTICE]


def test_the_compile_notice_names_what_compiles_and_that_other_kinds_compile_later(
        monkeypatch):
    """The notice names the technique and the kind of model being compiled and says that
    other techniques and models compile on their first run (it said "once per install",
    then came back for 8 of the tutorial's first commands)."""
    import click

    import torquesim.solvers as solvers
    from torquesim.cli import COMPILING_NOTICE, CompileReporter, model_kind
    from torquesim.errors import SimulationError

    seen = []
    monkeypatch.setattr(CompileReporter, "on_start",
                        lambda self, _event=None: seen.append(self.notice))

    def compile_then_stop(*args, **kwargs):  # a run that begins by compiling
        click.get_current_context().find_root().obj.on_start()
        raise SimulationError("stopped")

    monkeypatch.setattr(solvers, "simulate", compile_then_stop)
    assert main(["simulate", "--model", "builtin:squat-jump", "--method", "imex",
                 "--step", "0.25ms"]) == 1
    assert seen == [COMPILING_NOTICE.format(
        subject="the imex technique for a free body on 2 ground contacts (squat-jump)")]
    assert "once per technique and kind of model" in seen[0]
    assert "other techniques and models compile on their first run" in seen[0]
    assert "once per install," not in seen[0]
    assert model_kind(ts.load_model("builtin:arm-raise")) == "a 2-joint chain (arm-raise)"
    assert model_kind(ts.default_model()).startswith("a one-joint chain (elbow")
    # a command names what it compiles as it goes: the model's checks, then the loop; a
    # compile of the same subject says nothing more
    monkeypatch.undo()
    lines = []
    with CompileReporter(echo=lines.append) as reporter:
        reporter.subject = "the model's checks (builtin:squat-jump)"
        reporter.on_start()
        reporter.on_end()
        reporter.subject = "the imex technique for a free body"
        reporter.on_start()
        reporter.on_end()
        reporter.on_start()
        reporter.on_end()
    assert [line.split(" with Numba")[0] for line in lines] == [
        "compiling the model's checks (builtin:squat-jump)",
        "compiling the imex technique for a free body"]


def test_a_warm_run_says_nothing_about_compiling(capsys):
    assert main(["simulate", "--duration", "0.05"]) == 0
    capsys.readouterr()  # that run may have compiled (an empty cache)
    assert main(["simulate", "--duration", "0.05"]) == 0  # the kernels are now on disk
    assert "compiling" not in capsys.readouterr().err


def test_progress_reaches_a_log_at_least_every_ten_seconds(capsys, monkeypatch):
    """Not a terminal (a log file, CI): a progress line whenever 10 s passed since the last
    one (the clock is injected, not waited for)."""
    from torquesim.cli import Progress

    reporter = Progress(quiet=False)
    now = [0.0]
    reporter.clock = lambda: now[0]
    reporter.last_line = 0.0
    reporter.bars = False
    for done in range(1, 31):
        now[0] = done * 1.0  # one second per step
        reporter.step(done, 30, "least squares")
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln]
    assert lines == ["least squares: 10/30", "least squares: 20/30", "least squares: 30/30"]


def test_every_option_has_help_and_a_real_default():
    """What the CLI reference (mkdocs-click) shows: no click sentinel as a default, no option
    without help ("N/A"), whole-sentence summaries that are not cut; -h works everywhere."""
    import click

    from torquesim.cli import cli

    def walk(command, path):
        ctx = click.Context(command)
        for param in command.get_params(ctx):
            assert "Sentinel" not in repr(param.default), (path, param.name)
            if isinstance(param, click.Option):
                assert param.help, (path, param.opts)
        for name, sub in getattr(command, "commands", {}).items():
            summary = sub.get_short_help_str(limit=45)
            assert summary.endswith(".") and not summary.endswith("..."), (name, summary)
            walk(sub, f"{path} {name}")

    walk(cli, "torquesim")
    assert main(["batch", "sweep", "-h"]) == 0


def test_model_plot_draws_the_chain_and_the_unit_curves(tmp_path, capsys):
    png = tmp_path / "arm.png"
    assert main(["model", "arm-raise", "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.image

    height, width = matplotlib.image.imread(png).shape[:2]
    assert width > 1000 and height > 500
    capsys.readouterr()
    assert main(["model", "arm-raise"]) == 2  # nothing to write
    assert "--out" in capsys.readouterr().err


def test_model_paths_lists_every_path_with_its_value_and_range(capsys):
    """``model --paths``: one row per path the model holds a number at, with that number,
    and a path it lists is one that --vary takes."""
    from torquesim.model.paths import model_paths

    assert main(["model", "arm-raise", "--paths"]) == 0
    rows = capsys.readouterr().out.splitlines()
    arm = ts.load_model("builtin:arm-raise")
    assert rows[0].split() == ["path", "value", "unit", "allowed"]
    assert [row.split()[0] for row in rows[1:]] == model_paths(arm)
    row = next(r.split() for r in rows if r.startswith("forearm_hand.dumbbell.mass "))
    assert row[1:] == [f"{arm.segments[1].loads[0].mass:g}", "kg", "[0,", "1e3]"]


def test_simulate_animates_the_motion_as_a_stick_figure(tmp_path, capsys, monkeypatch):
    """25 frames per simulated second (played in real time once no slow motion is asked
    for), the stick figure at the simulated angles."""
    from PIL import Image

    import torquesim.plots as plots
    from torquesim.plots import segment_lines

    monkeypatch.setattr(plots, "MIN_PLAYING_TIME", 0.4)
    gif = tmp_path / "curl.gif"
    assert main(["simulate", "--duration", "0.4", "--animate", str(gif)]) == 0
    with Image.open(gif) as im:
        assert im.format == "GIF" and im.n_frames == 11
    assert not list(tmp_path.glob(".*"))  # no temporary file left
    capsys.readouterr()
    assert main(["simulate", "--duration", "0.4", "--animate", str(tmp_path / "x.mp4")]) == 2
    assert "--animate" in capsys.readouterr().err
    # the drawn geometry: a straight, hanging elbow chain ends one segment length below
    model = ts.load_model("builtin:arm-raise")
    lines = segment_lines(model, [[0.0, 0.0]])
    assert lines[0, 0, 1] == pytest.approx([0.0, -model.segments[0].length])
    assert lines[0, 1, 0] == pytest.approx(lines[0, 0, 1])  # the forearm starts there


def test_a_long_compile_reports_every_interval_until_done():
    """While compiling goes on, a line at every interval (a log is never silent for longer);
    none once it has ended, and the notice only once."""
    import time

    from torquesim.cli import CompileReporter

    def wait_for(count, lines, limit=10.0):  # polls: a loaded machine may be slow
        end = time.monotonic() + limit
        while len(lines) < count and time.monotonic() < end:
            time.sleep(0.02)
        return len(lines)

    lines = []
    with CompileReporter(interval=0.2, echo=lines.append) as reporter:
        COMPILING_NOTICE = reporter.notice
        reporter.on_start()
        reporter.on_start()  # a nested compile (a callee)
        reporter.on_end()
        assert wait_for(3, lines) >= 3
        reporter.on_end()
        time.sleep(0.1)  # a line being written as the compile ended
        assert lines[0] == COMPILING_NOTICE
        assert all(line.startswith("still compiling (") for line in lines[1:])
        count = len(lines)
        time.sleep(0.5)
        assert len(lines) == count  # nothing between compiles
        reporter.on_start()
        assert wait_for(count + 1, lines) > count
        reporter.on_end()
        assert COMPILING_NOTICE not in lines[count:]


def test_the_result_figure_draws_unit_torques_with_their_sign():
    """The torque panel: each unit's torque at its joint with its sign (extensors below
    zero), summing to the net torque drawn beside them; the optimisation figure draws the
    same rows for two runs, one line style each."""
    from torquesim.plots import plot_comparison, plot_result

    model = ts.load_model("builtin:elbow-curl").replace(duration=0.5)
    run = ts.simulate(model, "imex", 5e-3)
    ax_torque = plot_result(run).axes[1]
    lines = {line.get_label(): line.get_ydata() for line in ax_torque.get_lines()}
    flexor, extensor = lines["elbow_flexor (+)"], lines["elbow_extensor (−)"]
    assert (flexor >= 0).all() and (extensor <= 0).all() and extensor.min() < 0
    assert np.allclose(flexor + extensor, lines["net"], atol=1e-9)
    other = ts.simulate(model.replace(duration=0.5), "imex", 2.5e-3)
    labels = [line.get_label() for line in plot_comparison(run, other).axes[1].get_lines()]
    assert {"net, start", "net, optimum", "elbow_extensor (−), optimum"} <= set(labels)


def test_a_bound_is_written_low_comma_high_or_low_dot_dot_high():
    """--bound takes LOW..HIGH as --constrain writes a range (before, only LOW,HIGH);
    '0...1' (0..0.1 or 0...1?) and a reversed range are refused by name."""
    from torquesim.cli import _parse_assignments

    assert _parse_assignments(("a.b=0,0.5", "c.d=-0.1..0.2", "e.f=0.,1"), "--bound", 2) == \
        {"a.b": (0.0, 0.5), "c.d": (-0.1, 0.2), "e.f": (0.0, 1.0)}
    for bad, says in (("a.b=0...1", "LOW..HIGH"), ("a.b=0.5..0.1", "LOW < HIGH"),
                      ("a.b=1..2..3", "LOW..HIGH"), ("a.b=0.3,0.3", "LOW < HIGH")):
        with pytest.raises(ts.ModelError, match=says) as info:
            _parse_assignments((bad,), "--bound", 2)
        assert info.value.field == "--bound"
