"""One vocabulary of parameter paths (torquesim.model.paths) for compare --vary, batch sweep
--vary, fit --bound/--freeze and the API."""

import dataclasses
import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.fitting.parameters import ParameterSpace, with_ramps
from torquesim.model.paths import (
    allowed_at,
    canonical_path,
    get_parameter,
    model_paths,
    set_parameter,
)


@pytest.fixture(scope="module")
def arm():
    return ts.load_model("builtin:arm-raise")


def test_parameter_paths_follow_the_model_file(arm):
    assert set_parameter(arm, "shoulder_flexor.se_stiffness", 500).units[0] \
        .parameters.se_stiffness == 500
    assert set_parameter(arm, "units.elbow.extensor.isometric_torque", 40).units[3] \
        .parameters.isometric_torque == 40
    assert set_parameter(arm, "forearm_hand.dumbbell.mass", 3).segments[1].loads[0].mass == 3
    assert set_parameter(arm, "elbow.initial_angle", 0.5).joints[1].initial_angle == 0.5
    assert set_parameter(arm, "gravity", 1.6).gravity == 1.6
    assert math.isclose(set_parameter(ts.load_model("builtin:elbow-curl"),
                                      "flexor.se_stiffness", 700).units[0]
                        .parameters.se_stiffness, 700)


def test_get_and_set_are_inverse_and_change_nothing_else(arm):
    for path in ("shoulder_flexor.se_stiffness", "elbow.extensor.ramp1.level",
                 "shoulder_extensor.initial_level", "upper_arm.mass", "elbow.initial_angle",
                 "forearm_hand.dumbbell.distance", "gravity"):
        value = get_parameter(arm, path)
        assert set_parameter(arm, path, value) == arm
        other = value * 0.9 if value else 0.1
        changed = set_parameter(arm, path, other)
        assert get_parameter(changed, path) == pytest.approx(other)
        assert changed != arm


def test_activation_ramps_are_paths_and_the_fit_names_them_so(arm):
    """Every parameter the fit searches (UNIT.rampN.FIELD) is a model path whose value in the
    model the fit writes is the fitted one."""
    space = ParameterSpace.for_model(arm)
    x = np.array(space.lower) + 0.37 * (np.array(space.upper) - np.array(space.lower))
    fitted = with_ramps(arm, x, [u.activation.initial_level for u in arm.units])
    for name, value in zip(space.names, x, strict=True):
        assert canonical_path(arm, name) == name
        assert get_parameter(fitted, name) == pytest.approx(value)
    assert canonical_path(arm, "shoulder.flexor.ramp2.delay") == "shoulder_flexor.ramp2.delay"


@pytest.mark.parametrize("path, match", [
    ("flexor.se_stiffness", "not a numeric model field"),  # two joints: ambiguous
    ("tendon_slack", "not a numeric model field"),
    ("shoulder_flexor.ramp9.delay", "ramp1"),
    ("shoulder_flexor.initial_level", "static equilibrium"),
    ("forearm_hand.kettlebell.mass", "not a numeric model field"),
    # a misspelt path names the closest ones; the base's start is explained
    ("shoulder_flexor.se_stifness", r"\(closest: shoulder_flexor.se_stiffness, "),
    ("units.elbow_flexor.activation_time_constant", r"\(closest: elbow_flexor.activation_time,"),
    ("base.initial_height", "static equilibrium on its ground contacts"),
    ("duration", "the run's length is no parameter"),
])
def test_unknown_paths_are_one_clear_error(arm, path, match):
    with pytest.raises(ts.ModelError, match=match) as info:
        get_parameter(arm, path, "--vary")
    assert info.value.field == "--vary"


def test_an_invalid_value_names_the_path(arm):
    with pytest.raises(ts.ModelError) as info:
        set_parameter(arm, "elbow_flexor.se_stiffness", -1.0)
    assert info.value.field == "elbow_flexor.se_stiffness"


def test_points_and_contacts_are_paths():
    """A contact is named by its point (``toe.stiffness``), a point by its name
    (``heel.distance``): compare --vary and batch sweep --vary reach them as any field."""
    jump = ts.load_model("builtin:squat-jump")
    toe = get_parameter(jump, "points.toe.distance")
    for path, value in (("toe.stiffness", 2e6), ("contacts.heel.friction", 0.5),
                        ("toe.slip_speed", 0.05), ("points.toe.distance", toe - 0.002)):
        changed = set_parameter(jump, path, value)
        assert get_parameter(changed, path) == value
        assert set_parameter(changed, path, get_parameter(jump, path)) == jump
    soft = set_parameter(jump, "toe.stiffness", 2e6)
    assert soft.contacts[0].stiffness == 2e6 and soft.contacts[1] == jump.contacts[1]
    assert canonical_path(jump, "contacts.toe.stiffness") == "toe.stiffness"
    with pytest.raises(ts.ModelError, match="no ground contact") as info:
        get_parameter(jump, "hip_joint.stiffness", "--vary")
    assert info.value.field == "--vary"
    with pytest.raises(ts.ModelError, match="sink") as info:  # the model's own check
        set_parameter(jump, "toe.stiffness", 1e-3)
    assert info.value.field == "toe.stiffness"


def test_a_two_joint_unit_s_moment_arm_is_a_path():
    """``UNIT.second_arm`` reaches a two-joint unit's moment-arm ratio r, and the changed
    model's unit angle is ψ = q_j + d·r·q_j2 with the new r (r = 0: its own joint's angle);
    a one-joint unit has no second arm, a ratio beyond ±2 is refused naming the path."""
    model = ts.load_model("builtin:squat-jump-biarticular")
    gastrocnemius = model.units[model.unit_index("gastrocnemius")]
    assert get_parameter(model, "gastrocnemius.second_arm") == gastrocnemius.second_arm
    q = np.linspace(-0.4, 0.7, model.n_coordinates)
    j, j2 = model.joint_index(gastrocnemius.joint), model.joint_index("knee")
    u = model.unit_index("gastrocnemius")
    for r in (0.0, 0.3, -1.2):
        changed = set_parameter(model, "units.gastrocnemius.second_arm", r)
        assert changed.units[u].second_arm == r
        assert changed.unit_angles(q)[u] == pytest.approx(
            q[j] + gastrocnemius.direction * r * q[j2], abs=1e-15)
    assert canonical_path(model, "units.gastrocnemius.second_arm") == \
        "gastrocnemius.second_arm"
    with pytest.raises(ts.ModelError, match="spans one joint") as info:
        get_parameter(model, "plantarflexors.second_arm", "--vary")
    assert info.value.field == "--vary"
    with pytest.raises(ts.ModelError, match=r"allowed \[-2, 2\]") as info:
        set_parameter(model, "gastrocnemius.second_arm", 2.5)
    assert info.value.field == "gastrocnemius.second_arm"


def test_the_fit_and_the_optimiser_read_ramp_names_as_paths(arm):
    """The fit's ``--bound``/``--freeze`` and the optimiser's ``--free``/``--bound`` take ramp
    parameters in the path vocabulary: an alias, the optional ``units.`` group word; a unit or
    one of its ramps selects all its parameters; an unknown ramp is one error naming it."""
    space = ParameterSpace.for_model(arm)
    assert space.resolve("units.shoulder.flexor.ramp2.delay") == "shoulder_flexor.ramp2.delay"
    assert space.with_bounds("units.elbow_flexor.ramp1.level", 0.1, 0.6).lower[
        space.index("elbow_flexor.ramp1.level")] == 0.1
    assert space.select("units.shoulder.flexor.ramp2") == [
        "shoulder_flexor.ramp2.delay", "shoulder_flexor.ramp2.duration",
        "shoulder_flexor.ramp2.level"]
    assert space.select("elbow_extensor") == [n for n in space.names
                                              if n.startswith("elbow_extensor.")]
    for path in ("units.elbow_flexor.ramp1.delay", "elbow.flexor.ramp1.delay"):
        assert canonical_path(arm, path) == space.select(path)[0]
    with pytest.raises(ts.ModelError, match="no ramp 4") as info:
        space.select("elbow_flexor.ramp4", "free")
    assert info.value.field == "free"


def test_every_numeric_field_is_a_path_and_no_text_field_is():
    """Every field of the tables of allowed values is reachable by its path on the squat jump
    with a two-joint unit (its value read back, a value inside its range set), and a text
    field (a joint's ``positive``, a segment's ``parent``) is not a numeric path."""
    from torquesim.model import activation, chain, contact
    from torquesim.model.torque_generator import UNIT_FIELDS

    jump = ts.load_model("builtin:squat-jump-biarticular")
    jump = jump.replace(segments=(jump.segments[0], dataclasses.replace(
        jump.segments[1], loads=(chain.PointLoad("weight", 1.0, 0.1),)), *jump.segments[2:]),
        units=tuple(dataclasses.replace(u, activation_dynamics=activation.ActivationDynamics())
                    for u in jump.units))
    unit = next(u for u in jump.units if u.second_joint is not None)
    segment, joint = jump.segments[1], jump.joints[1]
    point = jump.contacts[0].point
    owners = [(unit.name, UNIT_FIELDS), (unit.name, chain.UNIT_GEOMETRY_FIELDS),
              (unit.name, activation.DYNAMICS_FIELDS),
              (f"{unit.name}.ramp1", activation.RAMP_FIELDS),
              (joint.name, chain.JOINT_FIELDS), (segment.name, chain.SEGMENT_FIELDS),
              (f"{segment.name}.weight", chain.LOAD_FIELDS), (point, contact.POINT_FIELDS),
              (point, contact.CONTACT_FIELDS),
              (None, {k: v for k, v in chain.CHAIN_FIELDS.items() if k != "duration"})]
    listed = model_paths(jump)  # what `torquesim model --paths` prints
    for owner, table in owners:
        for name in table:
            path = f"{owner}.{name}" if owner else name
            value = get_parameter(jump, path)
            assert value is None or isinstance(value, float), path
            assert path in listed and allowed_at(jump, path) is table[name], path
    assert len(listed) == len(set(listed))
    for path in listed:  # each listed value within its allowed range, and set back unchanged
        allowed, value = allowed_at(jump, path), get_parameter(jump, path)
        if not allowed.related:
            low, high = allowed.limits({})
            assert low <= value <= high, path
        same = set_parameter(jump, path, value)  # a parent distance left None is made explicit
        assert same == jump or path.endswith(".parent_distance") and np.array_equal(
            same.parent_distances(), jump.parent_distances()), path
    assert set_parameter(jump, f"{joint.name}.endstop_torque", 2.0).joints[1].endstop_torque \
        == 2.0
    # a parent distance left to the model reads as the parent's length, and can be set
    arm = ts.load_model("builtin:arm-raise")
    assert arm.segments[1].parent_distance is None
    assert get_parameter(arm, "forearm_hand.parent_distance") == arm.segments[0].length
    assert set_parameter(arm, "forearm_hand.parent_distance", 0.25).segments[1] \
        .parent_distance == 0.25
    with pytest.raises(ts.ModelError, match="hangs from the base"):
        get_parameter(arm, "upper_arm.parent_distance")
    for path in (f"{joint.name}.positive", f"{segment.name}.parent", f"{joint.name}.coordinate"):
        with pytest.raises(ts.ModelError, match="not a numeric model field"):
            get_parameter(jump, path)
