"""A 3D inverse-kinematics file mapped onto a planar model's joints
(torquesim.fitting.coordinate_map; fit --map, --column JOINT=EXPRESSION)."""

import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.cli import main
from torquesim.fitting import load_target
from torquesim.fitting.coordinate_map import default_map, parse_expression


def test_expressions_parse_to_coefficients_and_an_offset():
    assert parse_expression("-knee_angle_r", "f") == ({"knee_angle_r": -1.0}, 0.0)
    assert parse_expression("118.1 - ankle_angle_r", "f") == ({"ankle_angle_r": -1.0}, 118.1)
    assert parse_expression("pelvis_tilt + 2*hip - 0.5*hip + 3 - 1", "f") == (
        {"pelvis_tilt": 1.0, "hip": 1.5}, 2.0)
    for bad in ("", "a +", "2 ** a", "a b", "--a"):
        with pytest.raises(ts.ModelError, match="^f: "):
            parse_expression(bad, "f")


def _gait_file(path, model, run, knee_sign, lumbar=True):
    """An OpenSim-style 3D IK .mot (degrees, both legs, pelvis translations and rotations,
    lumbar, arms) whose right leg and pelvis make the planar run's posture: every planar
    angle is turned into OpenSim's coordinates by the relations of the module's docstring,
    with the trunk's lean split between pelvis tilt and lumbar extension."""
    deg = {j.name: np.degrees(run.angle(j.name)) for j in model.joints}
    foot = math.degrees(model.joints[0].initial_angle)
    ankle = (180.0 - foot) - deg["ankle"]
    knee_z = -deg["knee"]
    trunk = deg["foot_ground"] + deg["ankle"] + deg["knee"] + deg["hip"]  # absolute, planar
    lumbar_ext = 0.3 * (trunk - 180.0) if lumbar else np.zeros_like(trunk)
    pelvis = trunk - 180.0 - lumbar_ext
    hip_flexion = lumbar_ext - deg["hip"]
    n = run.time.size
    cols = {"time": run.time, "pelvis_tilt": pelvis, "pelvis_list": np.full(n, 1.5),
            "pelvis_rotation": np.full(n, -2.0), "pelvis_tx": np.linspace(0, 0.1, n),
            "pelvis_ty": np.full(n, 0.9), "pelvis_tz": np.zeros(n),
            "hip_flexion_r": hip_flexion, "hip_adduction_r": np.full(n, 3.0),
            "hip_rotation_r": np.zeros(n), "knee_angle_r": knee_sign * knee_z,
            "ankle_angle_r": ankle, "hip_flexion_l": hip_flexion + 2.0,
            "knee_angle_l": knee_sign * knee_z, "ankle_angle_l": ankle,
            "arm_flex_r": np.full(n, 20.0), "elbow_flex_r": np.full(n, 30.0)}
    if lumbar:
        cols["lumbar_extension"] = lumbar_ext
    lines = ["Coordinates", "version=1", f"nRows={n}", f"nColumns={len(cols)}", "inDegrees=yes",
             "endheader", "\t".join(cols)]
    lines += ["\t".join(f"{v:.8f}" for v in row) for row in np.column_stack(list(cols.values()))]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def jump():
    model = ts.load_model("builtin:squat-jump")
    return model, ts.simulate(model, "imex", step=1e-4, output_step=1 / 120)


@pytest.mark.parametrize("name, knee_sign, lumbar", [("gait2392", 1.0, True),
                                                     ("rajagopal2016", -1.0, True),
                                                     ("gait2392", 1.0, False)])
def test_a_default_map_gives_back_the_planar_angles(jump, name, knee_sign, lumbar, tmp_path):
    """A 3D IK file written from the squat jump's run (the right leg, pelvis and lumbar
    carrying the planar posture, other coordinates anything) mapped back with the default map:
    every planar joint angle within 1e-6° of the run's (a file without lumbar_extension reads
    it as 0, and says so)."""
    model, run = jump
    path = _gait_file(tmp_path / "ik.mot", model, run, knee_sign, lumbar)
    target = load_target(str(path), model, default_map(name, model))
    assert target.joints == ("foot_ground", "ankle", "knee", "hip")
    for row, joint in enumerate(target.joints):
        assert np.degrees(target.angles[row]) == pytest.approx(
            np.degrees(run.angle(joint)), abs=1e-6)
    assert ("absent, read as 0: lumbar_extension" in target.source) is not lumbar


def test_the_absolute_angles_agree_with_the_model_s_geometry(jump):
    """The relations the maps rest on, checked on the model: the foot's absolute angle plus
    the ankle, knee and hip angles is the trunk's absolute angle, and in the static squat the
    trunk leans forwards (below 180°) and the thigh points up and back (above 180°)."""
    model, run = jump
    deg = {j.name: math.degrees(j.initial_angle) for j in model.joints}
    thigh = deg["foot_ground"] + deg["ankle"] + deg["knee"]
    trunk = thigh + deg["hip"]
    assert 180.0 < thigh < 270.0 and 90.0 < trunk < 180.0


def test_fit_maps_by_name_file_and_column(jump, tmp_path, monkeypatch):
    """fit --map gait2392, --map FILE.toml and --column JOINT=EXPRESSION reach the fit's
    target with the planar angles."""
    import torquesim.fitting.outputs as outputs

    model, run = jump
    path = _gait_file(tmp_path / "ik.mot", model, run, 1.0)
    table = tmp_path / "map.toml"
    table.write_text("[targets.map]\n" + "\n".join(
        f'{j} = "{e}"' for j, e in default_map("gait2392", model).items()) + "\n")
    seen = []

    class Reached(Exception):
        pass

    def stop(problem, *_, **__):
        seen.append(problem.target)
        raise Reached

    monkeypatch.setattr(outputs, "fit_and_write", stop)
    for options in (["--map", "gait2392"], ["--map", str(table)],
                    ["--map", "rajagopal2016", "--column", "knee=-knee_angle_r",
                     "--column", "foot_ground=pelvis_tilt+hip_flexion_r+knee_angle_r"
                     f"+ankle_angle_r+{math.degrees(model.joints[0].initial_angle)}"]):
        with pytest.raises(Reached):
            main(["fit", "--model", "builtin:squat-jump", "--target", str(path), *options,
                  "--quiet", "--overwrite", "--out", str(tmp_path / "fit")])
        knee = seen[-1].angles[seen[-1].joints.index("knee")]
        assert np.degrees(knee) == pytest.approx(np.degrees(run.angle("knee")), abs=1e-6)


def test_bad_maps_are_one_line_errors(jump, tmp_path, capsys):
    model, run = jump
    path = _gait_file(tmp_path / "ik.mot", model, run, 1.0)
    cases = [
        (["--map", "gait2354"], "--map: 'gait2354'; allowed: gait2392, rajagopal2016"),
        (["--column", "knee=-knee_angle_x"], "--column: knee=-knee_angle_x: ik.mot has no "
                                             "column 'knee_angle_x'"),
        (["--column", "knee=2**knee_angle_r"], "--column knee: '2**knee_angle_r'"),
    ]
    for options, message in cases:
        assert main(["fit", "--model", "builtin:squat-jump", "--target", str(path), *options,
                     "--quiet", "--out", str(tmp_path / "fit")]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"error: {message}"), err
    assert main(["fit", "--model", "builtin:arm-raise", "--target", str(path), "--map",
                 "gait2392", "--quiet", "--out", str(tmp_path / "fit")]) == 2
    assert "the gait2392 map is for the squat jump's joints" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["squat-jump", "arm-raise", "knee-extension"])
def test_the_conventions_figure_draws_each_angle_from_its_zero_line(name, tmp_path):
    """Each joint's arc spans its drawn angle (|q| in degrees) and starts or ends on the zero
    line: the parent's axis carried on (for the root, the base direction); `--conventions`
    writes it, with the OpenSim maps below the jump."""
    from matplotlib.patches import Arc

    from torquesim.cli import conventions_figure

    model = ts.load_model(f"builtin:{name}")
    fig = conventions_figure(model)
    arcs = [p for p in fig.axes[0].patches if isinstance(p, Arc)]
    assert len(arcs) == len(model.joints)
    state = model.initial_state().state[:model.n_coordinates]
    free = model.base == "free"
    angles = model.kinematics(state)["angles"]
    for k, (arc, joint) in enumerate(zip(arcs, model.joints, strict=True)):
        q = float(state[model.n_base + k])
        if not free and abs(q) < 0.4:
            q = 0.7 if joint.endstop_lower_angle <= 0.7 <= joint.endstop_upper_angle else -0.7
        assert arc.theta2 - arc.theta1 == pytest.approx(abs(math.degrees(q)), abs=1e-9)
        if free:
            parent = model.parents[k]
            zero = math.degrees(model.base_angle if parent < 0 else angles[parent]) - 90.0
            assert min(abs(arc.theta1 - zero), abs(arc.theta2 - zero)) < 1e-9
    assert (len(fig.axes) == 2) == free  # the maps below the jump
    assert main(["model", name, "--conventions", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").stat().st_size > 10_000
