"""Named test cases for the numerical studies."""

from __future__ import annotations

import numpy as np

from ..model.activation import ActivationProfile
from ..model.elbow import ElbowModel, default_model


def smooth_case() -> tuple[ElbowModel, np.ndarray]:
    """A motion whose right-hand side is smooth along the whole solution (0.4 s).

    The default model with constant activations (flexor 0.6, extensor 0.3), started from the
    static-equilibrium state of those levels with the extensor SE stretched 0.002 rad further.
    From t = 0 the flexor shortens (ω_cc,F ≥ 0.16 rad/s) and the extensor lengthens
    (ω_cc,E ≤ −0.05 rad/s), so no unit crosses the kink of T_ω at ω_cc = 0, no CE velocity is
    clamped, no SE goes slack and the elbow stays between 10° and 28°, far from the end stops.
    Smallest CE time constant ≈ 1.1 ms (extensor), so RK4 is stable for h ≤ 3 ms.

    Returns
    -------
    model, initial_state
        Pass ``initial_state`` to :func:`torquesim.simulate`.
    """
    model = default_model().replace(flexor_activation=ActivationProfile(0.6),
                                    extensor_activation=ActivationProfile(0.3), duration=0.4)
    y0 = model.initial_state().state.copy()
    y0[3] -= 0.002
    return model, y0
