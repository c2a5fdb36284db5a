"""What the figures of a movement on the ground show: a jump drawn as a jump paper draws it
(ground reaction forces in body weights, centre of mass with take-off and apex, a strobe
with scaled force arrows, only the joints that have units), joints labelled with the motion a
growing angle is, and animations slowed down to be seen."""

from __future__ import annotations

import numpy as np
import pytest

import torquesim as ts
from torquesim.errors import ModelError


@pytest.fixture(scope="module")
def jump():
    return ts.simulate(ts.load_model("builtin:squat-jump"), "imex", 0.25e-3)


def _lines(ax) -> dict[str, np.ndarray]:
    return {line.get_label(): np.asarray(line.get_ydata(), dtype=float)
            for line in ax.get_lines()}


def _xlines(ax, label) -> list[float]:
    return [float(np.asarray(line.get_xdata())[0]) for line in ax.get_lines()
            if line.get_label() == label]


def test_a_jump_is_drawn_with_its_forces_in_body_weights_and_its_events(jump):
    """The first row after the strobe: the vertical force in body weights (the body weight
    line at 1; the force at the start, standing still in the squat, is 1 body weight), the
    horizontal force, the centre of mass's height and speeds; take-off on every panel at
    the run's take-off, the apex where the height peaks; no row for the free root (no
    units), one per joint with units, its torque axis named by the joint's motion."""
    from torquesim.plots import plot_jump

    fig = plot_jump(jump)
    model = jump.model
    cols = jump.columns()
    events = jump.ground_events()
    strobe, grf, com, speed, *joint_axes = fig.axes
    lines = _lines(grf)
    assert np.allclose(lines["vertical"], cols["grf_y"] / model.weight)
    assert lines["vertical"][0] == pytest.approx(1.0, abs=1e-3)  # static squat
    assert np.allclose(lines["body weight"], 1.0)
    assert np.allclose(lines["horizontal (forwards +)"], cols["grf_x"] / model.weight)
    for ax in (grf, com, speed):
        assert _xlines(ax, "take-off") == [pytest.approx(events.take_off)]
    assert _xlines(com, "apex") == [pytest.approx(events.apex_time)]
    assert np.allclose(_lines(com)["height"], cols["com_y"])
    assert np.allclose(_lines(speed)["vertical (up +)"], cols["com_speed_y"])
    acting = [j for j in model.joints if any(u.joint == j.name for u in model.units)]
    assert len(acting) == model.n_joints - 1  # the free root's angle has no units
    assert len(joint_axes) == 3 * len(acting)
    torque_labels = [ax.get_ylabel() for ax in joint_axes[1::3]]
    assert torque_labels == [f"{j.name} torque, {j.positive} + (N·m)" for j in acting]
    assert "hip torque, extension + (N·m)" in torque_labels


def test_the_strobe_draws_poses_at_take_off_and_apex_with_forces_to_scale(jump):
    """The strobe holds the take-off and apex poses (labelled), a ground force arrow per
    loaded pose whose height is FORCE_ARROW_SCALE m per body weight, a key arrow of one body
    weight, and the foot drawn as ankle-heel-toe (the heel on the foot)."""
    import matplotlib.pyplot as plt

    from torquesim.plots import FORCE_ARROW_SCALE, draw_strobe, outline_polygons

    fig, ax = plt.subplots()
    draw_strobe(ax, jump, poses=10)
    texts = [t.get_text() for t in ax.texts]
    assert any("take-off" in t for t in texts) and any("apex" in t for t in texts)
    arrows = [a for a in ax.texts if hasattr(a, "xy") and a.arrow_patch is not None]
    heights = sorted(a.xy[1] for a in arrows)
    cols = jump.columns()
    peak = cols["grf_y"].max() / jump.model.weight * FORCE_ARROW_SCALE
    assert heights[-1] <= peak + 1e-9
    assert FORCE_ARROW_SCALE in [pytest.approx(h) for h in heights]  # the key
    plt.close(fig)
    model = jump.model
    where = model.kinematics(jump.states[0, :model.n_coordinates])
    (foot,) = outline_polygons(model, where)
    heel = where["points"][[p.name for p in model.points].index("heel")]
    assert any(np.allclose(corner, heel) for corner in foot)
    assert np.allclose(foot[0], foot[-1])  # closed


def test_an_animation_plays_a_short_run_slowed_down_and_a_long_one_bounded():
    """The jump (0.55 s) plays at 0.1× real time (138 frames at 25 per second), a 10 s run
    in real time, a 60 s run in at most MAX_FRAMES frames, faster than real time."""
    from torquesim.plots import MAX_FRAMES, animation_times

    times, speed = animation_times(0.55, 25)
    assert speed == pytest.approx(0.1) and times.size == 138 and times[-1] <= 0.55
    assert np.allclose(np.diff(times), 0.1 / 25)
    times, speed = animation_times(10.0, 25)
    assert speed == 1.0 and times.size == 251
    times, speed = animation_times(60.0, 25)
    assert times.size == MAX_FRAMES and speed > 1.0 and times[-1] == pytest.approx(60.0)


def test_every_joint_says_which_motion_a_growing_angle_is():
    """The squat jump's hip extends and its ankle plantarflexes as their angles grow; every
    other preset's joints flex. A model file keeps it, writes each unit's direction as the
    motion it pulls towards, and refuses a motion that is not one."""
    from torquesim.io.model_file import model_from_dict, model_to_toml

    jump = ts.load_model("builtin:squat-jump")
    assert [j.positive for j in jump.joints] == ["counterclockwise", "plantarflexion",
                                                 "flexion", "extension"]
    assert [j.negative for j in jump.joints][1:] == ["dorsiflexion", "extension", "flexion"]
    for name in ("elbow-curl", "knee-extension", "arm-raise"):
        assert {j.positive for j in ts.load_model(f"builtin:{name}").joints} == {"flexion"}
    text = model_to_toml(jump)
    assert "direction = 1  # +1: pulls towards hip extension" in text
    assert "direction = -1  # -1: pulls towards hip flexion" in text
    import tomllib

    data = tomllib.loads(text)
    assert model_from_dict(data) == jump
    data["joints"][3]["positive"] = "extension please"
    with pytest.raises(ModelError, match=r"joints\[3\]\.positive.*allowed: flexion, "):
        model_from_dict(data)
