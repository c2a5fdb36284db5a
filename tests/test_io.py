"""Model TOML files and result tables."""

import json
import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.io import model_to_toml
from torquesim.io.atomic import write_atomic


def test_toml_round_trip_is_exact(tmp_path):
    model = ts.default_model().replace(
        initial_angle=math.radians(23.4), duration=2.5,
        extensor_activation=ts.ActivationProfile(0.15, (ts.Ramp(0.1, 0.2, 0.3),)),
        body=ts.BodyParameters(dumbbell_mass=7.25, endstop_torque=0.0),
        extensor=ts.TorqueGeneratorUnit(**{**ts.TorqueGeneratorUnit.extensor_default().as_dict(),
                                           "ce_damping": 0.25}))
    path = ts.save_model(model, tmp_path / "m.toml")
    assert ts.load_model(path) == model.to_chain()
    for name in ("elbow-curl", "knee-extension", "arm-raise"):
        preset = ts.load_model(f"builtin:{name}")
        assert ts.load_model(ts.save_model(preset, tmp_path / f"{name}.toml")) == preset


def test_partial_legacy_elbow_file_takes_defaults(tmp_path):
    """An elbow file of torquesim 0.1 ([body], [flexor], [extensor]) still loads."""
    path = tmp_path / "m.toml"
    path.write_text("[body]\ndumbbell_mass = 2\n")
    m = ts.load_model(path)
    assert m.segments[0].loads[0].mass == 2.0
    assert m.units[0].parameters == ts.default_model().flexor
    expected = ts.default_model().replace(body=ts.BodyParameters(dumbbell_mass=2.0)).to_chain()
    assert m == expected


@pytest.mark.parametrize("text, field", [
    ("[body]\ndumbell_mass = 2\n", "body.dumbell_mass"),
    ("[flexor]\nse_stiffness = -3\n", "flexor.se_stiffness"),
    ("[extensor]\nisometric_torque = 'big'\n", "extensor.isometric_torque"),
    ("duration = 0\n", "duration"),
    ("colour = 3\n", "colour"),
    ("[flexor.activation]\nramps = [{delay = 0.1, duration = 0, level = 0.5}]\n",
     "flexor.activation.ramps[0].duration"),
    ("[flexor.activation]\nramps = [{delay = 0.1, duration = 0.2, level = 1.5}]\n",
     "flexor.activation.ramps[0].level"),
    ("[flexor.activation]\nramps = [{delay = 0.1, level = 0.5}]\n",
     "flexor.activation.ramps[0].duration"),
    ("[extensor.activation]\ninitial_level = 'equilibrium'\n",
     "extensor_activation.initial_level"),
    ("[flexor]\nmin_differential_activation = 0.0\ndifferential_activation_rate = 0.05\n",
     "flexor.min_differential_activation"),
    ("this is = = not toml", "model"),
])
def test_bad_files_name_the_key(tmp_path, text, field):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ts.ModelError) as info:
        ts.load_model(path)
    assert info.value.field == field
    assert "\n" not in str(info.value)


def test_missing_file(tmp_path):
    with pytest.raises(ts.ModelError, match="cannot read"):
        ts.load_model(tmp_path / "nope.toml")


def test_toml_is_commented_with_units_and_sources():
    text = model_to_toml(ts.default_model())
    assert "se_stiffness = 600.0  # N m/rad" in text
    assert 'initial_level = "equilibrium"' in text
    assert "de Leva" in model_to_toml(ts.load_model("builtin:arm-raise"))


@pytest.mark.parametrize("suffix", [".csv", ".sto"])
def test_result_table_round_trip(tmp_path, suffix):
    result = ts.simulate(ts.default_model().replace(duration=0.2), "monolithic", 1e-4)
    path = tmp_path / f"run{suffix}"
    ts.save_result(result, path)
    table = ts.read_table(path)
    cols = result.columns()
    assert list(k for k in table if not k.startswith("_")) == list(cols)
    assert list(cols) == ["time", "elbow_flexion", "elbow_flexion_speed",
                          "theta_cc_elbow_flexor", "theta_cc_elbow_extensor",
                          "torque_elbow_flexor", "torque_elbow_extensor", "torque_net_elbow",
                          "torque_passive_elbow", "activation_elbow_flexor",
                          "activation_elbow_extensor", "omega_cc_elbow_flexor",
                          "omega_cc_elbow_extensor"]
    for name in cols:
        np.testing.assert_array_equal(table[name], cols[name])
    assert (tmp_path / f"run{suffix}.manifest.json").exists()
    if suffix == ".sto":
        head = path.read_text().splitlines()[:7]
        assert "inDegrees=no" in head and "endheader" in head
        assert head[2] == f"nRows={result.time.size}" and head[3] == "nColumns=13"
        assert table["_in_degrees"] == np.array(False)


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    def broken(tmp):
        tmp.write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        write_atomic(tmp_path / "out.csv", broken)
    assert list(tmp_path.iterdir()) == []


def test_output_files_honour_the_umask(tmp_path):
    import os

    old = os.umask(0o022)
    try:
        path = ts.save_model(ts.default_model(), tmp_path / "m.toml")
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o644


@pytest.mark.parametrize("where", ["/proc/torquesim-test.csv", "/proc/self/run.csv"])
def test_unwritable_output_path_is_one_line_exit_2(where, capsys):
    from torquesim.cli import main

    assert main(["simulate", "--duration", "0.01", "--out", where]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and where in err and err.count("\n") == 1


def test_a_failed_write_keeps_the_previous_file(tmp_path):
    path = tmp_path / "out.csv"
    path.write_text("previous\n")

    def broken(tmp):
        tmp.write_text("half")
        raise OSError(28, "No space left on device")

    with pytest.raises(ts.ModelError, match="No space left"):
        write_atomic(path, broken)
    assert path.read_text() == "previous\n" and sorted(tmp_path.iterdir()) == [path]


def test_one_fingerprint_tells_apart_what_it_must():
    """The one hasher of checkpoints, sweep chunks and batch fits: equal parts give equal
    fingerprints; a changed value, dtype, shape or split between parts does not."""
    import numpy as np

    from torquesim.io.fingerprint import fingerprint

    a = np.arange(6, dtype=float)
    base = fingerprint("model", a, ("imex", 5e-3))
    assert base == fingerprint("model", a.copy(), ("imex", 5e-3)) and len(base) == 16
    others = [fingerprint("model", a + 1e-12, ("imex", 5e-3)),
              fingerprint("model", a.reshape(2, 3), ("imex", 5e-3)),
              fingerprint("model", a.astype(np.float32), ("imex", 5e-3)),
              fingerprint("mode", "l", a, ("imex", 5e-3)),
              fingerprint("model", a, ("imex", 2.5e-3))]
    assert base not in others and len(set(others)) == len(others)


def test_summaries_are_json_every_reader_accepts():
    """A goal a run could not compute (NaN) or a failed run's error (inf) is written as
    null, not as NaN/Infinity (which strict parsers refuse); integers stay integers."""
    import json
    import math

    import numpy as np

    from torquesim.io.json_text import json_text

    text = json_text({"gain_percent": math.nan, "errors": [math.inf, 0.5, np.int64(3)],
                      "values": np.array([1.0, np.nan]), "ok": True, "n": np.float64(2.5)})

    def refuse(constant):
        raise ValueError(constant)

    data = json.loads(text, parse_constant=refuse)
    assert data == {"gain_percent": None, "errors": [None, 0.5, 3], "values": [1.0, None],
                    "ok": True, "n": 2.5}


def test_a_table_torquesim_wrote_is_read_back_as_a_target_in_its_own_units(tmp_path):
    """simulate --out run.csv, then fit --target run.csv: the table holds radians and its
    manifest says so; a CSV without one is read in degrees (the lab's default)."""
    from torquesim.fitting.target import load_target

    model = ts.default_model().replace(duration=0.2)
    result = ts.simulate(model, "monolithic", 1e-4)
    path = ts.save_result(result, tmp_path / "run.csv")
    info = json.loads((tmp_path / "run.csv.manifest.json").read_text())
    assert info["units"]["angles"] == "rad"
    target = load_target(str(path), model)
    expected = np.interp(target.time, result.time, result.q[:, 0])
    np.testing.assert_allclose(target.angles[0], expected, rtol=1e-12, atol=1e-15)
    (tmp_path / "run.csv.manifest.json").unlink()
    in_degrees = load_target(str(path), model)
    np.testing.assert_allclose(in_degrees.angles[0], np.radians(expected), rtol=1e-12)
