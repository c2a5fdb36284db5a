"""The choice of a run's step loop: what the loop is made of (`StepKinds`), made from the
packed model and exchange, and `run_step_loop`, which runs the loop of its technique
(`monolithic`, `partitioned` or `error_control`) from Python and from compiled callers (the
population kernels) alike."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import types
from numba.extending import overload

from ..model.body import BodyKinds, body_kinds, switch
from .coupling_layout import (
    ABSOLUTE_TOLERANCE,
    BODY_SOLVER,
    EVERY_STAGE,
    MUSCLE_SOLVER,
    ORDER,
    ROS2,
    SDIRK2,
)
from .error_control import error_controlled_partitioned
from .monolithic import monolithic_scratch_size, rk4_monolithic
from .partitioned import rk4_partitioned


class StepKinds(NamedTuple):
    """What a run's step loop is made of, each kind True or None (`switch`), the body's a
    `BodyKinds` or None: a loop given None for a kind drops the code of that kind when it
    compiles, and a run compiles only its own code (a fit one loop and one muscle solver,
    not all of them). `step_kinds` makes them; `_chosen_loop` passes them to the loop."""

    #: The monolithic loop (`rk4_monolithic`; the every-stage exchange too), else the
    #: partitioned one (`rk4_partitioned`): True or None.
    monolithic: bool | None
    #: The body's `BodyKinds`, None for one segment on a fixed pivot (q̈ one division;
    #: `check_body`).
    body: BodyKinds | None
    #: Some unit has an activation state (`check_unit_kinds`): True or None.
    dynamics: bool | None
    #: The partitioned loop's muscle part by SDIRK2 (IMEX), else by RK4 (None; None in the
    #: monolithic loop): each compiles only its kind of stage (`_muscle_part`).
    implicit_muscles: bool | None
    #: The partitioned loop's body part by ROS2, linearly implicit in its stiff forces
    #: (`_body_ros2`), else by RK4 (None; None in the monolithic loop).
    implicit_body: bool | None
    #: The error-controlled loop (`error_control.error_controlled_partitioned`, imex-ros2's
    #: step at steps its error estimate chooses), else a fixed step: True or None.
    error_control: bool | None = None


def step_kinds(monolithic: bool, seg, n_coordinates: int, coupling,
               dynamics: bool = False) -> StepKinds:
    """The `StepKinds` of the monolithic (else partitioned, under the packed ``coupling``)
    technique on the packed body ``seg`` of ``n_coordinates`` (`ChainModel.n_coordinates`)
    whose units have activation dynamics or not (``dynamics``: any unit has;
    `ChainModel.has_activation_dynamics`). The partitioned technique exchanging at every
    stage is monolithic RK4 (docs/model.md §4) and runs the monolithic loop."""
    monolithic = monolithic or int(coupling[ORDER]) == EVERY_STAGE
    implicit = not monolithic and int(coupling[MUSCLE_SOLVER]) == SDIRK2
    implicit_body = not monolithic and int(coupling[BODY_SOLVER]) == ROS2
    controlled = implicit and implicit_body and coupling[ABSOLUTE_TOLERANCE] > 0.0
    return StepKinds(switch(monolithic), body_kinds(seg, n_coordinates), switch(dynamics),
                     switch(implicit), switch(implicit_body), switch(controlled))


def model_step_kinds(model, monolithic: bool, exchange) -> StepKinds:
    """`step_kinds` of a `ChainModel`: its body and activation dynamics read off the
    model."""
    return step_kinds(monolithic, model.segment_array(), model.n_coordinates, exchange,
                      model.has_activation_dynamics)


def kind_on(kinds, name: str) -> bool:
    """Whether kind ``name`` of ``kinds`` (`StepKinds`) is on: read off the value (Python
    callers) or off its Numba type while compiling (`_run_step_loop_compiled`)."""
    if isinstance(kinds, types.BaseNamedTuple):
        return not isinstance(kinds.types[kinds.fields.index(name)], types.NoneType)
    return getattr(kinds, name) is not None


def _chosen_loop(kinds):
    """The call of the step loop the kinds choose, with the body's kinds and the units'
    switches as its arguments (`kind_on`): the same function runs from Python (calling the
    chosen loop's dispatcher) and is compiled for compiled callers (`_run_step_loop_compiled`).
    The loop gets the kinds typed bool or None as a Python True is (a literal True would
    compile a second copy of the loop for compiled callers, measured: the jump's IMEX loop
    compiled twice, 11–18 s each)."""
    if kind_on(kinds, "error_control"):
        def controlled(kinds, system, y0, h, n_steps, coupling, out, stats):
            for i in range(y0.shape[0]):
                out[0, i] = y0[i]
            error_controlled_partitioned(system, h, n_steps, coupling, out, stats, kinds.body,
                                         kinds.dynamics)
        return controlled
    if kind_on(kinds, "monolithic"):
        def monolithic(kinds, system, y0, h, n_steps, coupling, out, stats):
            for i in range(y0.shape[0]):
                out[0, i] = y0[i]
            scratch = np.empty(monolithic_scratch_size(system, y0.shape[0]))
            rk4_monolithic(system, h, n_steps, out, stats, scratch, kinds.body, kinds.dynamics)
        return monolithic

    def partitioned(kinds, system, y0, h, n_steps, coupling, out, stats):
        for i in range(y0.shape[0]):  # (a loop: a slice assignment compiles a shape check)
            out[0, i] = y0[i]
        rk4_partitioned(system, h, n_steps, coupling, out, stats, kinds.body, kinds.dynamics,
                        kinds.implicit_muscles, kinds.implicit_body)
    return partitioned


def run_step_loop(kinds, system, y0, h, n_steps, coupling, out, stats):
    """Run the step loop of the kinds ``kinds`` (`StepKinds`) on the packed model ``system``
    = (segments, joints, units, profiles) (`PackedChain`): `rk4_monolithic` or
    `rk4_partitioned` under the packed ``coupling``, for one segment or a chain, and in the
    partitioned loop its muscle solver; y0 the initial state, h the step (s), ``out``
    (n_steps + 1 rows of y) and ``stats`` (`new_stats`) filled. Only the chosen code is
    compiled. From Python the kinds choose in Python (`_chosen_loop`), which calls the chosen
    loop's dispatcher; compiled callers (the population kernel) get the chosen loop's call
    inlined (`_run_step_loop_compiled`), so that no wrapper is compiled around it: each
    compiled layer links and optimises the loop again (0.6–0.8 s of a cold first fit per
    layer). (A dispatcher passed as an argument would choose as well, but Numba's disk cache
    misses such compilations in every new process; an integer made literal compiles every
    branch once before it specialises.)"""
    _chosen_loop(kinds)(kinds, system, y0, h, n_steps, coupling, out, stats)


@overload(run_step_loop, inline="always")
def _run_step_loop_compiled(kinds, system, y0, h, n_steps, coupling, out, stats):
    """`run_step_loop` for compiled callers: the loop chosen by the kinds' Numba types while
    compiling, so that only the chosen loop is typed and compiled."""
    return _chosen_loop(kinds)
