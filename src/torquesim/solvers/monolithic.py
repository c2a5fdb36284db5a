"""Technique 2, monolithic: classical RK4 on the whole state y = (q, q̇, the units' states),
every stage evaluating the body and the muscles together by `rates.state_rates`, the
right-hand side SciPy's solvers use too (docs/model.md §4). The partitioned technique
exchanging at every stage is this loop (`step_loop.run_step_loop`)."""

from __future__ import annotations

import math

import numpy as np

from ..model.body import SEG_COUNT_COLUMN, body_work_size
from ..model.jit import njit
from .fixed_step import (
    NFEV_BODY,
    NFEV_MUSCLE,
    OK,
    STATUS,
    STEPS,
    SWEEPS,
    _check_state,
    _record_contacts,
    _record_stiffness,
    check_body,
    rk4_increment,
    rk4_stage_offset,
)
from .rates import (
    CE_VELOCITY,
    EXCITATION,
    GUESS,
    TIME_CONSTANT,
    UNIT_IO_ROWS,
    flat_arrays,
    state_rates,
    unit_excitation,
)


@njit(cache=True, error_model="numpy", inline="always")
def _predict(preceding, preceding_before, this_before):
    """Guess for a stage's CE velocity, rad/s: the value of the same stage one step earlier,
    shifted by the change of the preceding stage (stage 4 precedes stage 1) over that step.
    Within 1e-6 rad/s of the root on the default curl at 0.1 ms, so the root finder takes one
    step. The preceding stage's value while there is no history yet."""
    guess = this_before + (preceding - preceding_before)
    return guess if math.isfinite(guess) else preceding


#: Rows of `rk4_monolithic`'s scratch as long as the state (y, the 4 stage derivatives, the
#: stage) and as long as the units (this step's 4 stage CE velocities, the previous step's 4
#: and stage 4 two steps back, the 3 profile values, `state_rates`' unit rows).
_MONOLITHIC_STATE_ROWS = 6
_MONOLITHIC_UNIT_ROWS = 4 + 4 + 1 + 3 + UNIT_IO_ROWS


@njit(cache=True, error_model="numpy")
def monolithic_scratch_size(system, size):
    """Length of the scratch array `rk4_monolithic` works in, for the packed ``system`` and
    a state of ``size``."""
    n, n_units = system[1].shape[0], system[2].shape[0]
    return (_MONOLITHIC_STATE_ROWS * size + _MONOLITHIC_UNIT_ROWS * n_units + n
            + body_work_size(n, system[0]))


@njit(cache=True, error_model="numpy", _nrt=False)
def rk4_monolithic(system, h, n_steps, out, stats, scratch, body, dynamics):
    """Classical RK4 on the whole state y = (q, q̇, the units' states) (technique 2) of the
    model ``system`` = (segments, joints, units, profiles) (`PackedChain`) whose body is of
    the kinds ``body`` (`BodyKinds`, None for one segment on a fixed pivot: `check_body`)
    and whose units have activation dynamics (``dynamics`` True) or not (None; see
    `unit_rates`), in the array ``scratch`` of `monolithic_scratch_size`.

    Every stage evaluates body and muscles together (`state_rates`). ``out`` has shape
    (n_steps + 1, len(y)), the initial state in out[0]. The activation profiles are
    evaluated once per stage time. Each stage seeds the CE root finder with a prediction
    from the previous step (see `_predict`). Compiled without reference counting, as
    `state_rates` is: it allocates nothing, and calls no compiled function that returns an
    array.
    """
    seg = system[0]
    check_body(system[1], seg, body)
    n, nu, width, units, joints, rows = flat_arrays(system)
    size = out.shape[1]
    y = scratch[:size]
    k = scratch[size:5 * size].reshape((4, size))  # stage derivatives
    stage = scratch[5 * size:6 * size]
    o = _MONOLITHIC_STATE_ROWS * size
    # CE velocities (rad/s) of stages 1-4 in this step and in the previous one, and of stage 4
    # two steps back: the history the predictions use (NaN: none yet).
    now = scratch[o:o + 4 * nu].reshape((4, nu))
    seen = scratch[o + 4 * nu:o + 8 * nu].reshape((4, nu))
    seen4_before = scratch[o + 8 * nu:o + 9 * nu]
    levels = scratch[o + 9 * nu:o + 12 * nu].reshape((3, nu))  # e(t) at t, t + h/2, t + h
    unit_io = scratch[o + 12 * nu:o + _MONOLITHIC_UNIT_ROWS * nu].reshape((UNIT_IO_ROWS, nu))
    o += _MONOLITHIC_UNIT_ROWS * nu
    work = scratch[o + n:]  # the body's (`body_work_size`), after the joint torques'
    model = (n, nu, units, joints, seg, scratch[o:o + n], work)
    for i in range(size):
        y[i] = out[0, i]
    for u in range(nu):
        seen4_before[u] = np.nan
        for s in range(4):
            seen[s, u] = np.nan
    half = rk4_stage_offset(1, h)  # the middle stages' time after the step start
    contacts = seg.shape[0] > int(seg[0, SEG_COUNT_COLUMN])
    for u in range(nu):
        levels[0, u] = unit_excitation(0.0, rows, width, u)
    for step in range(n_steps):
        t = step * h
        for u in range(nu):
            levels[1, u] = unit_excitation(t + half, rows, width, u)
            levels[2, u] = unit_excitation((step + 1) * h, rows, width, u)
        for s in range(4):
            if s == 0:
                for i in range(size):
                    stage[i] = y[i]
            else:
                factor = rk4_stage_offset(s, h)
                for i in range(size):
                    stage[i] = y[i] + factor * k[s - 1, i]
            at = 0 if s == 0 else (1 if s < 3 else 2)
            for u in range(nu):
                unit_io[EXCITATION, u] = levels[at, u]
                if s == 0:
                    unit_io[GUESS, u] = _predict(seen[3, u], seen4_before[u], seen[0, u])
                else:
                    unit_io[GUESS, u] = _predict(now[s - 1, u], seen[s - 1, u], seen[s, u])
            state_rates(stage, k[s], unit_io, model, body, dynamics)
            for u in range(nu):
                now[s, u] = unit_io[CE_VELOCITY, u]
            if s == 0:
                for u in range(nu):
                    _record_stiffness(stats, t, h / unit_io[TIME_CONSTANT, u], u)
                if body is not None:
                    if contacts:
                        _record_contacts(stats, t, h, stage, n, seg, work, body.free_base)
        for u in range(nu):
            seen4_before[u] = seen[3, u]
            for s in range(4):
                seen[s, u] = now[s, u]
            levels[0, u] = levels[2, u]
        for i in range(size):
            y[i] += rk4_increment(k[0, i], k[1, i], k[2, i], k[3, i], h)
            out[step + 1, i] = y[i]
        stats[NFEV_BODY] += 4
        stats[NFEV_MUSCLE] += 4
        stats[STEPS] = step + 1
        status = _check_state(y, n, joints)
        if status != OK:
            stats[STATUS] = status
            return
    stats[SWEEPS] = n_steps
