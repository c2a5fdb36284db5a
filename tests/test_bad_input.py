"""The bad inputs found from outside on 0.2.0: each is one clean line naming the field (exit 2
on the command line, a ModelError or TypeError in Python), and nothing is written or damaged.
"""

import re
from pathlib import Path

import pytest

import torquesim as ts
from torquesim.cli import main
from torquesim.io.model_file import model_to_toml


def one_line(capsys, argv, code=2):
    got = main(argv)
    # the one-time notice before Numba compiles (a cold cache) and its "still compiling"
    # lines on a slow or loaded machine are not part of the error
    err = "\n".join(line for line in capsys.readouterr().err.strip().splitlines()
                    if not line.startswith(("compiling ",
                                            "still compiling"))).strip()
    assert got == code, err
    assert err.startswith("error: ") and "\n" not in err and "Traceback" not in err
    return err


def chain_toml(**replace) -> str:
    text = model_to_toml(ts.load_model("builtin:arm-raise"))
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new, 1)
    return text


# ------------------------------------------------------------------ model files

@pytest.mark.parametrize("old, new, field", [
    ("length = 0.2817", "length = 1e300", "segments[0].length"),
    ("distance = 0.337", "distance = 1e300", "segments[1].loads[0].distance"),
    ("eccentric_torque_max = 81.0", "eccentric_torque_max = 1e300",
     "units[0].eccentric_torque_max"),
    ("min_differential_activation = 0.9", "min_differential_activation = 0.0",
     "units[0].min_differential_activation"),
    ("se_stiffness = 480.0", "se_stiffness = 1e300", "units[0].se_stiffness"),
    ("mass = 1.9783", 'mass = "heavy"', "segments[0].mass"),
])
def test_model_values_out_of_range_name_the_field_once(tmp_path, capsys, old, new, field):
    path = tmp_path / "m.toml"
    path.write_text(chain_toml(**{old: new}))
    err = one_line(capsys, ["simulate", "--model", str(path)])
    assert f"error: {field}:" in err and "segments[0].segments[0]" not in err
    assert len(err) < 400 and "000000000" not in err


def test_a_missing_length_on_a_proximal_segment_is_an_error(tmp_path, capsys):
    text = model_to_toml(ts.load_model("builtin:arm-raise"))
    line = next(ln for ln in text.splitlines() if ln.startswith("length = "))
    path = tmp_path / "m.toml"
    path.write_text(text.replace(line, "", 1))
    assert "segments[0].length: is missing" in one_line(capsys, ["simulate", "--model",
                                                                  str(path)])


@pytest.mark.parametrize("content", [b"", b"# nothing but a comment\n"])
def test_an_empty_model_file_is_an_error_not_the_default_curl(tmp_path, capsys, content):
    path = tmp_path / "empty.toml"
    path.write_bytes(content)
    assert "is empty" in one_line(capsys, ["simulate", "--model", str(path)])


def test_a_byte_order_mark_is_accepted(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + model_to_toml(ts.load_model("builtin:arm-raise")).encode())
    assert ts.load_model(path).n_joints == 2


def test_a_coordinate_named_time_is_refused(tmp_path, capsys):
    text = model_to_toml(ts.load_model("builtin:elbow-curl"))
    path = tmp_path / "m.toml"
    path.write_text(text.replace('coordinate = "elbow_flexion"', 'coordinate = "time"'))
    assert "coordinate" in one_line(capsys, ["simulate", "--model", str(path)])


def test_an_imex_run_is_not_advised_to_use_imex():
    from torquesim.solvers.simulation import _advice_text

    run = ts.simulate(ts.default_model(), "imex", 3.0, check=False)
    assert run.message and "'imex'" not in run.message
    assert "'imex'" not in _advice_text(1e-3, implicit=True)
    assert "'imex'" not in _advice_text(0.0, implicit=True)
    assert "'imex'" in _advice_text(1e-3)


# ------------------------------------------------------------------ simulate

@pytest.mark.parametrize("value", ["nan", "inf", "-1"])
def test_a_tolerance_that_is_not_a_number_is_refused(capsys, value):
    assert "--tolerance" in one_line(capsys, ["simulate", "--tolerance", value])


def test_a_manifest_that_cannot_be_written_leaves_no_table(tmp_path, capsys):
    out = tmp_path / "curl.csv"
    (tmp_path / "curl.csv.manifest.json").mkdir()  # a directory where the manifest goes
    err = one_line(capsys, ["simulate", "--duration", "0.1", "--out", str(out)])
    assert "--out" in err and not out.exists()


def test_plot_errors_name_the_plot_option(capsys):
    assert one_line(capsys, ["simulate", "--duration", "0.1", "--plot",
                             "/proc/torquesim.png"]).startswith("error: --plot")


def test_the_advice_search_gives_up_after_bounded_work(monkeypatch):
    """Plain partitioned RK4 on the arm raise at 0.1 ms breaks the stability limit and never
    agrees with itself to 1e-3 rad at smaller steps: 0.2 searched 8 halvings (434 s). The
    search now stops at runs of `ADVICE_MAX_STEPS` (1e6) steps and advises the implicit
    methods; its work is counted here, not timed, under a bound of 2e5 (the same search,
    about a sixth of the work: one halving and its check)."""
    import importlib

    module = importlib.import_module("torquesim.solvers.simulation")
    monkeypatch.setattr(module, "ADVICE_MAX_STEPS", 200_000)

    steps = []
    original = module._fixed_step

    def counted(model, packed, y0, method, step, coupling):
        result = original(model, packed, y0, method, step, coupling)
        steps.append(result.cost.steps)
        return result

    monkeypatch.setattr(module, "_fixed_step", counted)
    run = ts.simulate(ts.load_model("builtin:arm-raise"), "partitioned", 1e-4, check=False,
                      tolerance=None)
    assert run.stability.exceeded and "imex" in run.message
    assert max(steps) <= 200_000 and sum(steps) <= 600_000
    assert len(steps) >= 3  # the first run, then at least one halving and its check


def test_a_huge_run_is_announced_before_it_starts(tmp_path, capsys, monkeypatch):
    import torquesim.cli as cli

    monkeypatch.setattr(cli, "LARGE_RUN_STEPS", 1000)
    code = main(["simulate", "--duration", "0.2", "--step", "0.1ms"])
    err = capsys.readouterr().err
    assert code == 0 and err.startswith("note: this run takes 2,000 steps")


# ------------------------------------------------------------------ fit

@pytest.mark.parametrize("extra, field", [
    (["--bound", "elbow.flexor.ramp1.level=0.2,0.2"], "--bound"),  # names the option
    (["--step", "1e-9"], "step"),
    (["--freeze", "elbow.flexor.ramp1.delay=0.9", "--bound",
      "elbow.flexor.ramp1.delay=0,0.5"], "--freeze elbow_flexor.ramp1.delay"),
    (["--freeze", "elbow.flexor.ramp1.delay=0.1", "--freeze",
      "elbow.flexor.ramp1.delay=0.2"], "--freeze"),
    (["--column", "elbow=time"], "time"),
    # model fields: one the fit sets itself, a range outside the field's, a misspelt one
    (["--bound", "elbow.initial_angle=0,1"], "--bound elbow.initial_angle: a fit starts"),
    (["--bound", "elbow_flexor.se_stiffness=-5,900"],
     "--bound elbow_flexor.se_stiffness: -5 is out of range; allowed (0, 1e+06]"),
    (["--bound", "elbow_flexor.se_stifness=200,900"], "or a model field given a range"),
    (["--freeze", "elbow.initial_angle=0.3"], "--freeze elbow.initial_angle: a fit starts"),
    (["--freeze", "elbow_flexor.se_stiffness=-3"], "--freeze elbow_flexor.se_stiffness: -3"),
])
def test_fit_options_that_cannot_work_are_one_line_and_leave_no_folder(tmp_path, capsys,
                                                                         extra, field):
    target = tmp_path / "t.csv"
    target.write_text("time,elbow\n" + "".join(f"{i * 0.01},{10 + i}\n" for i in range(50)))
    out = tmp_path / "fit"
    err = one_line(capsys, ["fit", "--target", str(target), "--out", str(out), *extra])
    assert field in err
    assert not out.exists()


# ------------------------------------------------------------------ Python API

def test_an_unknown_joint_names_the_joints():
    r = ts.simulate(ts.default_model().replace(duration=0.05))
    with pytest.raises(ts.ModelError, match="allowed: elbow"):
        r.angle("hip")


def test_api_arguments_of_the_wrong_kind_are_named(tmp_path):
    with pytest.raises(TypeError, match="result"):
        ts.save_result("x", tmp_path / "x.csv")
    with pytest.raises(ts.ModelError, match="cannot read"):
        ts.read_table(tmp_path / "missing.csv")
    with pytest.raises(ts.ModelError, match="initial_state"):
        ts.simulate(initial_state="x")
    from torquesim.batch import sweep

    with pytest.raises(ts.ModelError, match="--samples"):
        sweep("builtin:elbow-curl", ["flexor.se_stiffness=uniform(400,800)"], samples="4")


def test_a_single_vary_string_is_one_distribution_not_its_characters():
    from torquesim.batch import sweep

    table, _ = sweep("builtin:elbow-curl", "flexor.se_stiffness=uniform(400,800)", samples=2,
                     step=2e-3)
    assert list(table.columns[:2]) == ["sample", "flexor.se_stiffness"] and len(table) == 2


# ------------------------------------------------------------------ batch

def test_batch_settings_that_fail_every_row_fail_the_command(tmp_path, capsys):
    out = tmp_path / "b"
    assert "nope.toml" in one_line(capsys, ["batch", "fit", "builtin:curl", "--model",
                                            str(tmp_path / "nope.toml"), "--out", str(out)])
    assert "--step" in one_line(capsys, ["batch", "fit", "builtin:curl", "--step", "0",
                                         "--out", str(out)])
    assert not out.exists()


def test_a_binary_manifest_is_one_line(tmp_path, capsys):
    manifest = tmp_path / "m.csv"
    manifest.write_bytes(bytes(range(256)) * 4)
    assert "--manifest" in one_line(capsys, ["batch", "fit", "--manifest", str(manifest),
                                             "--out", str(tmp_path / "b")])


@pytest.mark.parametrize("address", ["notaurl", ":abc", "http://", "tcp://host:99999"])
def test_a_malformed_scheduler_is_refused_before_anything_is_written(tmp_path, capsys,
                                                                      address):
    out = tmp_path / "s"
    assert "--scheduler" in one_line(capsys, ["batch", "sweep", "--vary",
                                              "flexor.se_stiffness=uniform(400,800)",
                                              "--out", str(out), "--scheduler", address])
    assert not out.exists()


def test_a_sweep_does_not_replace_another_sweep(tmp_path, capsys):
    out = str(tmp_path / "s")
    vary = ["--vary", "flexor.se_stiffness=uniform(400,800)", "--step", "2ms"]
    assert main(["batch", "sweep", *vary, "--samples", "2", "--out", out, "--quiet"]) == 0
    before = (tmp_path / "s" / "sweep.csv").read_bytes()
    capsys.readouterr()
    assert "holds another sweep" in one_line(capsys, ["batch", "sweep", *vary, "--samples",
                                                      "3", "--out", out, "--quiet"])
    assert (tmp_path / "s" / "sweep.csv").read_bytes() == before
    assert main(["batch", "sweep", *vary, "--samples", "3", "--out", out, "--quiet",
                 "--overwrite"]) == 0


def test_an_inaccurate_sweep_says_so_and_exits_1_unless_accepted(tmp_path, capsys):
    """A tolerance no step down to 20 ms / 2⁵ meets (1e-6°): the samples are named, exit 1;
    accepted, exit 0 (0.2 exited 0 on radians-off rows, guard "ok")."""
    argv = ["batch", "sweep", "--model", "builtin:arm-raise", "--vary",
            "shoulder.flexor.se_stiffness=uniform(400,500)", "--samples", "2", "--step",
            "20ms", "--tolerance", "1e-6", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "a")]) == 1
    err = capsys.readouterr().err
    assert "2 of 2 samples cannot be made accurate by halving the step 5 times (samples 0, 1;" \
        in err and "\n" not in err.strip()
    assert main([*argv, "--out", str(tmp_path / "b"), "--accept-inaccurate"]) == 0
    table = (tmp_path / "b" / "sweep.csv").read_text().splitlines()
    assert "step_s" in table[0].split(",") and len(table) == 3


def test_the_same_target_twice_is_fitted_once():
    from torquesim.batch.fits import expand_targets

    jobs = expand_targets(["builtin:curl", "builtin:curl"])
    assert len(jobs) == 1


def test_numbers_in_messages_are_short():
    flexor = ts.TorqueGeneratorUnit.flexor_default()
    with pytest.raises(ts.ModelError) as info:
        ts.TorqueGeneratorUnit(**{**flexor.as_dict(), "se_stiffness": 10**300})
    assert "1e+300 is out of range" in str(info.value) and len(str(info.value)) < 120


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux's /proc")
@pytest.mark.parametrize("argv", [
    ["simulate", "--out", "/proc/curl.csv"],
    ["fit", "--out", "/proc/fit-out"],
    ["compare", "--out", "/proc/compare-out"],
    ["batch", "sweep", "--vary", "se_stiffness=100..200", "--out", "/proc/sweep-out"],
])
def test_an_output_folder_that_cannot_be_written_is_refused_before_any_work(capsys, argv):
    """A folder that exists but takes no new file (permissions alone do not tell: /proc)
    is refused at once, naming the option, not after the run."""
    err = one_line(capsys, argv)
    assert err.startswith(f"error: --out: cannot write '{argv[-1]}': nothing can be created "
                          "in '/proc'")


def test_an_unknown_model_name_lists_the_presets(capsys, tmp_path):
    err = one_line(capsys, ["model", "elbow", "--out", str(tmp_path / "m.toml")])
    assert "neither a built-in model nor a file" in err and "squat-jump" in err
    assert not (tmp_path / "m.toml").exists()


@pytest.mark.parametrize("old, new, field", [
    ("gravity = 9.81", "gravity = 0", "gravity"),
    ("stiffness = 5000000.0", "stiffness = 1e-300", "contacts[0].stiffness"),
])
def test_a_body_that_cannot_stand_is_one_error_without_warnings(tmp_path, old, new, field):
    """Without gravity, or on contacts too soft to hold the body, there is no standing start:
    a ModelError naming the field, and no numerical warning from the search for one."""
    import warnings

    text = model_to_toml(ts.load_model("builtin:squat-jump"))
    assert old in text
    path = tmp_path / "m.toml"
    path.write_text(text.replace(old, new, 1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(ts.ModelError, match=f"^{re.escape(field)}: "):
            ts.simulate(ts.load_model(path), "imex", 2.5e-4, duration=0.05)
    assert [str(w.message) for w in caught] == []


@pytest.mark.parametrize("text, says", [
    ("target\n", "no targets below the header"),
    ("file,model\nbuiltin:curl,builtin:elbow-curl\n", "needs a header with 'target'"),
])
def test_a_manifest_without_targets_says_which_part_is_missing(tmp_path, capsys, text, says):
    manifest = tmp_path / "manifest.csv"
    manifest.write_text(text)
    err = one_line(capsys, ["batch", "fit", "--manifest", str(manifest), "--out",
                            str(tmp_path / "out")])
    assert says in err and not (tmp_path / "out").exists()
