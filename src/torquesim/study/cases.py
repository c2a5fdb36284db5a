"""Named test cases for the numerical studies."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..model.activation import ActivationProfile
from ..model.chain import ChainModel
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
        Pass ``initial_state`` to `torquesim.simulate`.
    """
    model = default_model().replace(flexor_activation=ActivationProfile(0.6),
                                    extensor_activation=ActivationProfile(0.3), duration=0.4)
    y0 = model.initial_state().state.copy()
    y0[model.to_chain().layout.unit_state(1)] -= 0.002  # the extensor's θ_cc
    return model, y0


def smooth_chain_case() -> tuple[ChainModel, np.ndarray]:
    """A two-joint motion whose right-hand side is smooth along the whole solution (0.25 s).

    The arm-raise preset with constant activations: both extensors at 0.3, both flexors 0.45
    (shoulder) and 0.3 (elbow) above the level that holds the start; started from the static
    equilibrium of the extensor levels with each extensor SE stretched 0.005 rad further.
    Along the motion both flexors shorten (ω_cc ≥ 0.2 rad/s) and both extensors lengthen
    (ω_cc ≤ −0.02 rad/s), no CE velocity is clamped and no SE goes slack (checked in the
    tests); the shoulder reaches ≈18° and the elbow ≈22°. Smallest CE time constant ≈ 0.63 ms,
    so RK4 is stable for h ≤ 1.7 ms.

    Returns
    -------
    model, initial_state
        Pass ``initial_state`` to `torquesim.simulate`.
    """
    from ..model.presets import preset

    arm = preset("arm-raise")
    extensor_level = 0.3
    held = arm.replace(units=tuple(
        replace(u, activation=ActivationProfile(None if u.direction == 1 else extensor_level))
        for u in arm.units), duration=0.25)
    start = held.initial_state()
    bump = {"shoulder": 0.45, "elbow": 0.3}
    units = tuple(replace(u, activation=ActivationProfile(start.levels[i] + bump[u.joint]))
                  if u.direction == 1 else u for i, u in enumerate(held.units))
    y0 = start.state.copy()
    for i, unit in enumerate(held.units):
        if unit.direction == -1:
            y0[held.layout.unit_state(i)] -= 0.005
    return held.replace(units=units), y0
