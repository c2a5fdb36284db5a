"""Body parameters and the static-equilibrium start."""

import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.model.body import passive_energy, passive_torque
from torquesim.solvers.rates import chain_derivative


def test_inertia_and_passive_torque_match_model_md(model):
    assert model.body.elbow_inertia == pytest.approx(0.653145, abs=1e-9)
    joint = model.to_chain().joint_array()[0]  # end-stop columns first, as passive_torque reads
    assert passive_torque(math.radians(10), joint) == pytest.approx(0.030481, abs=1e-6)


def test_passive_torque_is_minus_gradient_of_its_energy(model):
    b = model.to_chain().joint_array()[0]
    for theta in (-0.05, 0.1, 1.5, 2.6, 2.7):
        numeric = -(passive_energy(theta + 1e-7, b) - passive_energy(theta - 1e-7, b)) / 2e-7
        assert passive_torque(theta, b) == pytest.approx(numeric, rel=1e-6)


def test_initial_state_matches_model_md(model):
    start = model.initial_state()
    assert start.flexor_level == pytest.approx(0.205878, abs=1e-6)
    assert start.state[2] == pytest.approx(0.186777, abs=1e-6)
    assert start.state[3] == pytest.approx(0.161189, abs=1e-6)


@pytest.mark.parametrize("angle_deg", [5.0, 10.0, 45.0, 90.0, 120.0])
def test_initial_state_is_an_equilibrium(angle_deg):
    m = ts.default_model().replace(initial_angle=math.radians(angle_deg))
    chain = m.to_chain()
    rates = chain_derivative(0.0, chain.initial_state().state, *chain.pack())
    assert rates[0] == 0.0
    assert abs(rates[1]) < 1e-12  # no angular acceleration
    assert abs(rates[2]) < 1e-9 and abs(rates[3]) < 1e-9  # both CEs isometric


def test_start_the_flexor_cannot_hold():
    with pytest.raises(ts.ModelError, match="initial_angle.*activation 1.9"):
        ts.default_model().replace(body=ts.BodyParameters(dumbbell_mass=40.0),
                                   initial_angle=math.radians(90))


def test_start_where_the_flexor_would_push():
    # hanging straight, the end stop pushes (1 N·m) more than a resting extensor pulls
    with pytest.raises(ts.ModelError, match="initial_angle.*push"):
        ts.default_model().replace(extensor_activation=ts.ActivationProfile(0.0),
                                   initial_angle=0.0)


@pytest.mark.parametrize("field, value", [
    ("segment_mass", 0.0), ("segment_mass", -1.6), ("segment_com_distance", 0.0),
    ("segment_inertia", -0.1), ("dumbbell_mass", -5.0), ("dumbbell_distance", 0.0),
    ("endstop_angle_scale", 0.0), ("gravity", math.nan), ("endstop_upper_angle", -0.5)])
def test_bad_body_parameters_name_the_field(field, value):
    with pytest.raises(ts.ModelError) as info:
        ts.BodyParameters(**{field: value})
    assert info.value.field == field


@pytest.mark.parametrize("field, value", [("duration", 0.0), ("duration", -1.0),
                                          ("initial_angle", 4.0)])
def test_bad_model_fields(field, value):
    with pytest.raises(ts.ModelError) as info:
        ts.default_model().replace(**{field: value})
    assert info.value.field == field


def test_zero_dumbbell_gives_the_bare_forearm():
    m = ts.default_model().replace(body=ts.BodyParameters(dumbbell_mass=0.0,
                                                          dumbbell_inertia=0.0))
    assert m.body.elbow_inertia == pytest.approx(0.0763)
    assert np.isfinite(m.initial_state().flexor_level)


def test_every_field_s_bounds_are_written_once():
    """Each numeric field of a model class has its allowed values in one table (`Allowed`):
    the class's docstring says the same bounds (PointLoad's said [0, inf) where the check held
    1000 kg; the unit's said (0, inf) for 8 fields the check held to finite limits), the
    model file's comment is made from it, and the check refuses a value just beyond either
    end and an open end itself, naming the field."""
    import dataclasses
    import math
    import re

    from torquesim.io.model_file import FIELD_DOCS
    from torquesim.model import activation, chain, contact
    from torquesim.model.torque_generator import UNIT_FIELDS, TorqueGeneratorUnit

    load = chain.PointLoad("dumbbell", 5.0, 0.3, 0.01)
    segment = chain.Segment("thigh", 8.0, 0.2, 0.5, 0.4)
    joint = chain.Joint("knee", 0.5, endstop_lower_angle=-0.1, endstop_upper_angle=2.5)
    arm = ts.load_model("builtin:squat-jump-biarticular")
    two_joint = next(u for u in arm.units if u.second_joint is not None)
    assert set(UNIT_FIELDS) == set(TorqueGeneratorUnit.field_names())
    cases = [(TorqueGeneratorUnit.flexor_default(), UNIT_FIELDS),
             (load, chain.LOAD_FIELDS), (segment, chain.SEGMENT_FIELDS),
             (joint, chain.JOINT_FIELDS), (two_joint, chain.UNIT_GEOMETRY_FIELDS),
             (arm, chain.CHAIN_FIELDS), (arm.points[0], contact.POINT_FIELDS),
             (arm.contacts[0], contact.CONTACT_FIELDS),
             (activation.Ramp(0.1, 0.2, 0.5), activation.RAMP_FIELDS),
             (activation.ActivationProfile(0.3), activation.PROFILE_FIELDS),
             (activation.ActivationDynamics(), activation.DYNAMICS_FIELDS)]
    for owner, table in cases:
        doc = " ".join(type(owner).__doc__.split())
        values = {f.name: getattr(owner, f.name) for f in dataclasses.fields(owner)}
        assert set(table) <= set(values), type(owner)
        for name, allowed in table.items():
            said = re.search(rf"\b{name} : (.*?)(?= \w+ : |$)", doc)
            assert said and f"Bounds {allowed.interval()}" in said.group(1), (type(owner), name)
            if owner is not load and table is not activation.RAMP_FIELDS \
                    and table is not activation.PROFILE_FIELDS:
                assert FIELD_DOCS[name] == allowed.text(), name
            low, high = allowed.limits(values)
            for bound, is_open, outward in ((low, allowed.low_open, -1),
                                            (high, allowed.high_open, 1)):
                if math.isinf(bound):
                    continue
                beyond = bound + outward * 1e-9 * max(1.0, abs(bound))
                for bad in ([beyond, bound] if is_open else [beyond]):
                    with pytest.raises(ts.ModelError) as info:
                        dataclasses.replace(owner, **{name: bad})
                    assert info.value.field == name, (name, str(info.value))
