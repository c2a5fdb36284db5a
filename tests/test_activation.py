"""Quintic activation ramps."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import torquesim as ts
from torquesim.model.activation import activation
from torquesim.model.elbow import default_flexor_activation


def test_default_flexor_profile_levels_and_timing():
    prof = default_flexor_activation()
    packed = prof.to_array(0.205878)
    (s1, e1), (s2, e2), (s3, e3) = prof.ramp_times()
    assert (s1, e1) == pytest.approx((0.058, 0.369))
    assert s2 == pytest.approx(0.369 + 0.498) and e2 == pytest.approx(s2 + 0.613)
    assert s3 == pytest.approx(e2 + 0.511) and e3 == pytest.approx(s3 + 0.462)
    assert activation(0.0, packed) == 0.205878
    assert activation(s1, packed) == 0.205878
    assert activation(e1, packed) == pytest.approx(0.556)
    assert activation(0.5 * (e1 + s2), packed) == pytest.approx(0.556)
    assert activation(0.5 * (s1 + e1), packed) == pytest.approx(0.5 * (0.205878 + 0.556))
    assert activation(e3 + 1.0, packed) == pytest.approx(0.26)


ramps = st.lists(st.tuples(st.floats(0, 0.5), st.floats(0.01, 0.5), st.floats(0, 1)),
                 min_size=1, max_size=4)


@settings(max_examples=60, deadline=None)
@given(a0=st.floats(0, 1), spec=ramps)
def test_activation_stays_between_levels(a0, spec):
    prof = ts.ActivationProfile(a0, tuple(ts.Ramp(*r) for r in spec))
    t = np.linspace(0, sum(d + r for d, r, _ in spec) + 0.1, 2001)
    a = prof(t)
    levels = [a0] + [lv for *_, lv in spec]
    assert np.all(a >= min(levels) - 1e-12) and np.all(a <= max(levels) + 1e-12)


def test_c2_smoothness_at_ramp_ends():
    prof = ts.ActivationProfile(0.1, (ts.Ramp(0.2, 0.3, 0.9),))
    packed = prof.to_array()
    eps = 1e-5
    for t_edge in (0.2, 0.5):
        def a(t):
            return activation(t, packed)
        for side in (-1, 1):
            t = t_edge + side * 2 * eps
            first = (a(t + eps) - a(t - eps)) / (2 * eps)
            second = (a(t + eps) - 2 * a(t) + a(t - eps)) / eps**2
            # velocity and acceleration vanish at both ends of a quintic ramp
            assert abs(first) < 1e-4 and abs(second) < 0.1
    # and are large in the middle: the test above can fail
    mid = 0.35
    assert (activation(mid + eps, packed) - activation(mid - eps, packed)) / (2 * eps) > 4.0


@pytest.mark.parametrize("kwargs, field", [
    (dict(delay=-0.1, duration=0.3, level=0.5), "delay"),
    (dict(delay=0.1, duration=0.0, level=0.5), "duration"),
    (dict(delay=0.1, duration=0.3, level=1.2), "level"),
    (dict(delay=0.1, duration=0.3, level=-0.01), "level")])
def test_bad_ramps(kwargs, field):
    with pytest.raises(ts.ModelError) as info:
        ts.Ramp(**kwargs)
    assert info.value.field == field


def test_bad_initial_level():
    with pytest.raises(ts.ModelError, match="initial_level"):
        ts.ActivationProfile(1.5)
