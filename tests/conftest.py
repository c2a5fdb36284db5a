import numpy as np
import pytest

import torquesim as ts


@pytest.fixture(scope="session")
def model():
    return ts.default_model()


@pytest.fixture(scope="session")
def reference(model):
    """Radau at rtol 1e-11 on the 1 ms grid: 'truth' for the default curl."""
    return ts.simulate(model, "reference", rtol=1e-11, atol=1e-13)


def max_angle_error(result, reference) -> float:
    """Max |θ − θ_ref| (rad) at the times both grids share (the result's step and the
    reference's output step are multiples of one another)."""
    ratio = (reference.time[1] - reference.time[0]) / result.step
    if ratio >= 1:
        k = int(round(ratio))
        return float(np.max(np.abs(result.theta[::k] - reference.theta)))
    k = int(round(1 / ratio))
    return float(np.max(np.abs(result.theta - reference.theta[::k])))
