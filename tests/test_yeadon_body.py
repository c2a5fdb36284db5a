"""Built-in models made from a subject's own measurements (Yeadon 1990's inertia model through
the yeadon package; torquesim.model.yeadon_body and anthropometry.for_measured)."""

import math
from pathlib import Path

import numpy as np
import pytest
import yeadon

import torquesim as ts
from torquesim.cli import main
from torquesim.model.anthropometry import for_measured
from torquesim.model.preset_names import PRESET_NAMES
from torquesim.model.yeadon_body import read_measurements

MALE = Path(__file__).resolve().parent.parent / "examples" / "subject" / "yeadon_male1.txt"


@pytest.fixture(scope="module")
def body():
    return read_measurements(MALE)


def test_the_parts_hold_every_solid_once_where_yeadon_has_them(body):
    """Two thighs, shanks and feet and head-arms-trunk make the package's whole body: its
    mass, and its centre of mass height rebuilt from each part's position along its limb
    (z from the hip: thigh down from 0, shank from the knee, foot from the ankle)."""
    human = yeadon.Human(str(MALE))
    p = body.parts
    legs = ("thigh", "shank", "foot")
    assert 2 * sum(p[n].mass for n in legs) + p["head_arms_trunk"].mass == pytest.approx(
        human.mass, rel=1e-12)
    knee, ankle = -human.meas["Lj3L"], -human.meas["Lj5L"]
    heights = {"thigh": -p["thigh"].com, "shank": knee - p["shank"].com,
               "foot": ankle - p["foot"].com, "head_arms_trunk": p["head_arms_trunk"].com}
    moment = sum((2 if n in legs else 1) * p[n].mass * z for n, z in heights.items())
    assert moment / human.mass == pytest.approx(float(np.ravel(human.center_of_mass)[2]),
                                                abs=1e-12)


def test_the_limb_lengths_are_the_measured_ones(body):
    human = yeadon.Human(str(MALE))
    m = human.meas
    assert body.parts["thigh"].length == pytest.approx(m["Lj3L"])
    assert body.parts["shank"].length == pytest.approx(m["Lj5L"] - m["Lj3L"])
    assert body.parts["forearm"].length == pytest.approx(m["La4L"] - m["La2L"])
    assert body.height == pytest.approx(0.08 + m["Lj5L"] + m["Ls5L"] + m["Ls8L"])


def test_weighing_scales_the_masses_not_the_shape():
    """--body-mass scales every density alike: masses and inertias by the mass ratio, centres
    and lengths unchanged; and the package's class-wide density table is left as it was (it
    scales it in place: a later body would have come out scaled too)."""
    plain = read_measurements(MALE)
    heavy = read_measurements(MALE, body_mass=70.0)
    again = read_measurements(MALE)
    ratio = 70.0 / plain.mass
    assert heavy.mass == pytest.approx(70.0)
    for name, part in plain.parts.items():
        assert heavy.parts[name].mass == pytest.approx(ratio * part.mass, rel=1e-9)
        assert heavy.parts[name].inertia == pytest.approx(ratio * part.inertia, rel=1e-9)
        assert heavy.parts[name].com == pytest.approx(part.com, rel=1e-9)
    assert again.mass == pytest.approx(plain.mass, rel=1e-12)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_every_preset_can_be_made_from_measurements(name, body):
    """Each preset's segments become the measured ones (both legs where it lumps them): the
    whole-body jump weighs what was measured; the arm presets' forearm-and-hand is the
    measured forearm and hand laid end to end; the inertia about the joint exceeds m·c²."""
    model = for_measured(ts.load_model(f"builtin:{name}"), body)
    p = body.parts
    for seg in model.segments:
        assert seg.inertia_about_joint > seg.mass * seg.com_distance ** 2
    if name == "squat-jump":
        total = sum(s.total_mass for s in model.segments)
        assert total == pytest.approx(body.mass, rel=1e-12)
        shank = model.segments[1]
        assert shank.mass == pytest.approx(2 * p["shank"].mass)
        # the jump's shank runs from the ankle: its centre is measured from there
        assert shank.com_distance == pytest.approx(p["shank"].length - p["shank"].com)
        assert shank.inertia_about_joint == pytest.approx(2 * p["shank"].inertia_about(
            p["shank"].length - p["shank"].com))
    if name == "elbow-curl":
        arm = model.segments[0]
        assert arm.mass == pytest.approx(p["forearm"].mass + p["hand"].mass)
        assert arm.length == pytest.approx(p["forearm"].length + p["hand"].length)


def test_a_measured_jumper_stands_and_jumps(tmp_path):
    """The made jump starts at rest on both contacts (the trunk turned so the centre of mass
    sits over the feet where the preset's does at the joints' angles; settled on the
    contacts, within 1 mm) and leaves the ground."""
    out = tmp_path / "me.toml"
    assert main(["model", "squat-jump", "--measurements", str(MALE), "--body-mass", "70",
                 "--out", str(out)]) == 0
    model = ts.load_model(str(out))
    assert "Yeadon measurements, yeadon_male1.txt" in model.notes[0]
    preset = ts.load_model("builtin:squat-jump")

    def com_x(m):
        state = m.initial_state().state[: m.n_base + m.n_joints]
        return float(np.ravel(m.kinematics(state)["com"])[0] - state[0])

    from torquesim.model.anthropometry import _com_x

    assert _com_x(model, model.segments, model.joints) == pytest.approx(
        _com_x(preset, preset.segments, preset.joints), abs=1e-9)
    assert com_x(model) == pytest.approx(com_x(preset), abs=1e-3)
    events = ts.simulate(model, "imex", step=2.5e-4).ground_events()
    assert events.take_off is not None and 0.2 < events.flight_height < 0.4


@pytest.mark.parametrize("edit, message", [
    (("Lj3L: 42.6", "Lj3L: abc"), "Lj3L = 'abc'; allowed: a positive number"),
    (("Lj3L: 42.6", "Lj3L: -42.6"), "Lj3L = -42.6; allowed: a positive number"),
    (("Lj3L: 42.6\n", ""), "Lj3L is missing"),
    (("Lj5L: 81.6", "Lj5L: 20"), "Lj5L = 20 is not beyond Lj4L = 56.5"),
    (("measurementconversionfactor :  .01", "measurementconversionfactor : 1"),
     "they make a body of"),
])
def test_bad_measurement_files_are_one_line_errors(edit, message, tmp_path, capsys):
    text = MALE.read_text()
    assert edit[0] in text
    bad = tmp_path / "bad.txt"
    bad.write_text(text.replace(edit[0], edit[1]))
    out = tmp_path / "x.toml"
    assert main(["model", "squat-jump", "--measurements", str(bad), "--out", str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines()
           if not line.startswith("note:")]
    assert len(err) == 1 and err[0].startswith("error: --measurements: ") and message in err[0]
    assert not out.exists()


def test_measurements_take_sex_and_age_for_strengths_and_refuse_model_files(tmp_path, capsys):
    """--sex and --age with --measurements change the strengths only (Anderson's ratios), not
    the measured segments."""
    out, older = tmp_path / "x.toml", tmp_path / "o.toml"
    assert main(["model", "squat-jump", "--measurements", str(MALE), "--out", str(out)]) == 0
    assert main(["model", "squat-jump", "--measurements", str(MALE), "--sex", "female",
                 "--age", "60", "--out", str(older)]) == 0
    a, b = ts.load_model(str(out)), ts.load_model(str(older))
    assert [s.mass for s in a.segments] == [s.mass for s in b.segments]
    knee = [{u.name: u for u in m.units}["knee_extensors"].parameters.isometric_torque
            for m in (a, b)]
    assert knee[1] / knee[0] == pytest.approx(0.128 / 0.163, rel=1e-12)
    assert main(["model", "squat-jump", "--measurements", str(MALE), "--age", "101",
                 "--out", str(tmp_path / "z.toml")]) == 2
    assert "error: --age: 101 is out of range; allowed [18, 100] years" in \
        capsys.readouterr().err
    assert main(["model", "elbow-curl", "--out", str(out)]) == 0
    assert main(["model", str(out), "--measurements", str(MALE), "--out",
                 str(tmp_path / "y.toml")]) == 2
    assert "--measurements: " in capsys.readouterr().err
    assert math.isfinite(read_measurements(MALE).height)
