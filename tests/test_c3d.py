"""Force platforms from a C3D file (through ezc3d): summed in the lab's frame, onto a fit's
target (torquesim.io.force_plates.read_c3d_plates)."""

import math
import sys

import numpy as np
import pytest

import torquesim as ts
from torquesim.cli import main
from torquesim.io.force_plates import read_c3d_plates, read_plates

ezc3d = pytest.importorskip("ezc3d")


def _add_int(c3d, group, name, values, shape):
    """An integer parameter (ezc3d's Python helper stores numbers as floats, and the platform
    reader wants TYPE, USED and CHANNEL as integers)."""
    from ezc3d import ezc3d as swig

    parameter = swig.Parameter(name, "")
    parameter.set(swig.VecInt([int(v) for v in np.asarray(values).reshape(-1, order="F")]),
                  swig.VecUInt([int(n) for n in shape]))
    c3d._storage["parameters"].add_parameter(group, parameter)


def write_c3d(path, rate, point_rate, first_frame, on_plates, centres_mm):
    """A C3D file with one type-2 platform per entry of ``on_plates`` ((3, n) force on the
    plate in the lab's axes, N; zero moments, so each centre of pressure is its plate's
    centre ``centres_mm``, (x, y) mm), analog rate ``rate``, a marker at ``point_rate``."""
    n = on_plates[0].shape[1]
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [point_rate]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = ["marker"]
    c3d.add_parameter("POINT", "UNITS", "mm")
    c3d["data"]["points"] = np.zeros((4, 1, round(n * point_rate / rate)))
    c3d["data"]["points"][3] = 1.0
    c3d["parameters"]["ANALOG"]["RATE"]["value"] = [rate]
    labels, analogs = [], np.zeros((1, 6 * len(on_plates), n))
    for p, force in enumerate(on_plates):
        labels += [f"{q}{p + 1}" for q in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
        analogs[0, 6 * p:6 * p + 3] = force
    c3d["parameters"]["ANALOG"]["LABELS"]["value"] = labels
    c3d["data"]["analogs"] = analogs
    count = len(on_plates)
    _add_int(c3d, "FORCE_PLATFORM", "USED", [count], (1,))
    _add_int(c3d, "FORCE_PLATFORM", "TYPE", [2] * count, (count,))
    _add_int(c3d, "FORCE_PLATFORM", "ZERO", [1, 0], (2,))
    corners = np.zeros((3, 4, count))
    for p, (x, y) in enumerate(centres_mm):
        corners[:, :, p] = [[x + 300, x - 300, x - 300, x + 300],
                            [y + 200, y + 200, y - 200, y - 200], [0, 0, 0, 0]]
    c3d.add_parameter("FORCE_PLATFORM", "CORNERS", corners)
    c3d.add_parameter("FORCE_PLATFORM", "ORIGIN", np.zeros((3, count)))
    _add_int(c3d, "FORCE_PLATFORM", "CHANNEL",
             np.arange(1, 6 * count + 1).reshape(count, 6).T, (6, count))
    c3d["header"]["points"]["first_frame"] = first_frame
    c3d.write(str(path))
    return path


class Sampled:
    """The jump's run at 960 Hz (time, grf_x, grf_y), as a lab's analog channels."""

    def __init__(self, run):
        self.time = np.arange(528) / 960.0  # 66 frames of 8 analog samples
        columns = run.columns()
        self.columns = {k: np.interp(self.time, run.time, columns[k]) for k in ("grf_x",
                                                                                "grf_y")}


@pytest.fixture(scope="module")
def jump():
    model = ts.load_model("builtin:squat-jump")
    run = ts.simulate(model, "imex", 1e-4)
    lab = Sampled(run)
    return model, run, lab


def _lab_file(tmp_path, columns, time, name="trial.c3d"):
    """The jump's forces on two plates in a lab whose forward axis is −y and up z, written as
    the plates read them (the force on the plates), from frame 36 at 120 Hz (t0 = 0.3 s)."""
    share = 0.5 + 0.1 * np.sin(2 * np.pi * 2 * time)
    plates = []
    for part in (share, 1.0 - share):
        on_body = np.vstack([np.zeros_like(time), -columns["grf_x"] * part,
                             columns["grf_y"] * part])  # lab x, y, z: forward is −y
        plates.append(-on_body)
    return write_c3d(tmp_path / name, 960.0, 120.0, 36, plates, [(0.0, -200.0), (0.0, -800.0)])


def test_two_platforms_sum_to_the_body_s_force_in_its_own_frame(jump, tmp_path):
    """Forward −y, up z; the file holds the force on the plates: read back as the force on
    the body, forwards and up, to the file's float precision; the centre of pressure is the
    plates' centres (0.2 and 0.8 m forwards) weighted by their vertical forces; the time
    starts at the first frame (36 / 120 Hz = 0.3 s) at the analog rate."""
    _, _, lab = jump
    c = lab.columns
    path = _lab_file(tmp_path, c, lab.time)
    totals = read_plates(path, axes="-y,z")
    assert totals.rate == 960.0 and totals.plates == ("platform 1", "platform 2")
    assert totals.time[0] == pytest.approx(0.3) and np.diff(totals.time) == pytest.approx(
        1 / 960)
    scale = c["grf_y"].max()
    assert np.max(np.abs(totals.force_y - c["grf_y"])) < 1e-6 * scale
    assert np.max(np.abs(totals.force_x - c["grf_x"])) < 1e-6 * scale
    assert "turned into the force on the body" in totals.note
    share = 0.5 + 0.1 * np.sin(2 * np.pi * 2 * lab.time)
    loaded = c["grf_y"] > 20.0
    expected = 0.2 * share + 0.8 * (1.0 - share)
    assert np.max(np.abs(totals.cop_x[loaded] - expected[loaded])) < 1e-6
    assert np.all(np.isnan(totals.cop_x[~loaded]))


def test_the_same_file_read_in_the_wrong_frame_is_another_force(jump, tmp_path):
    """x,z (the default) reads the lateral axis as forwards: no horizontal force at all."""
    _, _, lab = jump
    c = lab.columns
    totals = read_c3d_plates(_lab_file(tmp_path, c, lab.time), "x,z")
    assert np.max(np.abs(totals.force_x)) < 1e-9 * c["grf_y"].max()


def test_fit_takes_c3d_forces_onto_its_target(jump, tmp_path, monkeypatch, capsys):
    """`fit --forces trial.c3d --lab-axes -y,z`: the target's force is the plates' sum on the
    motion's clock (both on the lab's: the C3D's first frame is at 0.3 s, and so is the
    motion's), filtered at 50 Hz."""
    from .conftest import fit_target, write_angle_csv

    model, run, lab = jump
    c = run.columns()
    plates = _lab_file(tmp_path, lab.columns, lab.time)
    frames = np.arange(0.0, 0.55, 1 / 120)
    angles = write_angle_csv(tmp_path / "angles.csv", 0.3 + frames, model,
                             [np.interp(frames, run.time, np.degrees(run.angle(j.name)))
                              for j in model.joints])
    target = fit_target(["--model", "builtin:squat-jump", "--target", str(angles), "--forces",
                         str(plates), "--lab-axes=-y,z", "--quiet", "--out",
                         str(tmp_path / "fit")], monkeypatch)
    push = target.elapsed < 0.2
    assert target.time[0] == pytest.approx(0.3)
    assert target.channels["grf_y"][push] == pytest.approx(
        np.interp(target.elapsed[push], run.time, c["grf_y"]), abs=0.02 * model.weight)
    out = capsys.readouterr().out
    assert "2 plate(s) summed" in out and "lab axes -y,z (forwards, up)" in out
    assert math.isfinite(target.channels["grf_x"].sum())


@pytest.mark.parametrize("axes", ["x,x", "x", "w,z", "x,z,y", "-,z"])
def test_lab_axes_are_two_distinct_axes(axes, jump, tmp_path, capsys):
    _, _, lab = jump
    path = _lab_file(tmp_path, lab.columns, lab.time)
    assert main(["fit", "--model", "builtin:squat-jump", "--target", "builtin:squat-jump",
                 "--forces", str(path), f"--lab-axes={axes}", "--quiet", "--out",
                 str(tmp_path / "fit")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --") and "\n" not in err and not (tmp_path / "fit").exists()


def test_bad_c3d_files_are_one_line_errors(tmp_path, monkeypatch):
    from torquesim.errors import ModelError

    junk = tmp_path / "junk.c3d"
    junk.write_bytes(b"not a c3d file at all" * 10)
    with pytest.raises(ModelError) as info:
        read_plates(junk, axes="x,z")
    assert info.value.field == "--forces" and "junk.c3d" in str(info.value)
    bare = ezc3d.c3d()
    bare["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    bare["parameters"]["POINT"]["LABELS"]["value"] = ["marker"]
    bare["data"]["points"] = np.ones((4, 1, 10))
    bare.write(str(tmp_path / "bare.c3d"))
    with pytest.raises(ModelError) as info:
        read_plates(tmp_path / "bare.c3d")
    assert "no force platform" in str(info.value)
    monkeypatch.setitem(sys.modules, "ezc3d", None)  # as if not installed
    with pytest.raises(ModelError) as info:
        read_plates(tmp_path / "bare.c3d")
    assert "needs the ezc3d package" in str(info.value)
