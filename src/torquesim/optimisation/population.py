"""A population of candidate activation profiles simulated together, in compiled parallel
threads: the motion of every candidate at every step, for goals computed afterwards."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..fitting.objective import PROFILE_SIZE, RUN_OK, pack_profile, run_status
from ..fitting.parameters import PER_UNIT
from ..model.body import body_work_size, ground_outputs
from ..solvers import fixed_step as fs
from ..solvers.rates import unit_excitation


@njit(cache=True, parallel=True, error_model="numpy")
def simulate_population(population, loop, coupling, y0, step, n_steps, seg, joints, units,
                        levels, explicit_muscles, ground, states, activations, outputs,
                        status):
    """Simulate every row of ``population`` (m × 9U ramp vectors, `fitting.parameters`) with
    the step loop the switches ``loop`` choose (`fixed_step.step_loop_switches`), unit u
    starting at ``levels[u]``. Fills, per candidate j: ``states[j]`` (steps + 1 rows of y),
    ``activations[j]`` (units × steps + 1, the profiles' values), with ``ground`` the
    `GROUND_OUTPUTS` of a body on the ground at every step into ``outputs[j]`` (4 × steps + 1),
    and ``status[j]`` (`fitting.objective.run_status`)."""
    n = joints.shape[0]
    for j in prange(population.shape[0]):
        seg_j, joints_j, units_j = seg.copy(), joints.copy(), units.copy()
        y0_j, coupling_j = y0.copy(), coupling.copy()
        profiles = np.zeros((levels.shape[0], PROFILE_SIZE))
        for u in range(levels.shape[0]):
            pack_profile(population[j], u * PER_UNIT, levels[u], profiles[u])
        stats = np.zeros(fs.STATS_SIZE)
        fs.run_step_loop(*loop, y0_j, step, n_steps, seg_j, joints_j, units_j, profiles,
                         coupling_j, states[j], stats)
        flat = profiles.ravel()
        for u in range(levels.shape[0]):
            for k in range(n_steps + 1):
                activations[j, u, k] = unit_excitation(k * step, flat, PROFILE_SIZE, u)
        status[j] = run_status(stats, explicit_muscles)
        if ground and status[j] == RUN_OK:
            _ground_outputs_of_run(states[j], n, seg_j, joints_j.ravel(), outputs[j],
                                   loop[fs.SWITCH_FREE_BASE], loop[fs.SWITCH_TREE])


@njit(cache=True, error_model="numpy")
def _ground_outputs_of_run(states, n, seg, joints, out, free_base, tree):
    """`GROUND_OUTPUTS` at every row of ``states`` into the columns of ``out`` (4 × rows);
    ``free_base`` and ``tree`` the body's switches (`body_switches`): with free_base None
    (no ground) nothing is compiled or done."""
    if free_base is not None:
        work = np.zeros(body_work_size(n, seg))
        torque = np.zeros(n)
        values = np.empty(4)
        for k in range(states.shape[0]):
            ground_outputs(states[k], n, seg, joints, torque, work, values, tree)
            for c in range(4):
                out[c, k] = values[c]
