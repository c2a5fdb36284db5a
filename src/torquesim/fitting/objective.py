"""The population kernel and the fit's objective, compiled.

`simulate_population` simulates a population of candidate activation ramps in parallel
threads: the one kernel of fits and optimisations. `population_residuals` turns a fit's
simulated population into residual vectors.

The residual vector r of a candidate (all angles in degrees, times in s) has, for every scored
joint j with weight w_j (weights sum to 1) and target sample k = 1…K,

    angle      √(w_j/K) · (q_j(t_k) − q*_j(t_k))
    velocity   w_ω · √(w_j/K) · (q̇_j(t_k) − q̇*_j(t_k)) · 1 s                  (w_ω > 0)
    end        w_end · √w_j · (q_j(T) − q*_j(T)),  w_end · √w_j · (q̇_j(T) − q̇*_j(T)) · 1 s
    effort     √(w_a/K) · max(a_u(t_k) − rest_u, 0)  for every unit u         (w_a > 0)
    channel    s_c/√K · (y_c(t_k) − y*_c(t_k))  for every target channel c of a body on the
               ground: total GRF in N with s_c = w_grf/(m·g), centre of mass in m with
               s_c = w_com (`torquesim.model.body.ground_outputs`, linear between steps)

so that ‖r‖² = Σ_j w_j·MSE_j + w_ω²·(velocity MSE) + w_end²·(end errors²) + w_a·Σ_u mean_k
(a_u − rest_u)₊² + Σ_c s_c²·MSE_c. With every weight 0 and one joint, ‖r‖ is the RMS angle
error. The score is ‖r‖ (degrees). A run that goes non-finite, diverges, exceeds the RK4
stability limit anywhere in a ground contact (unless the body part is implicit, ROS2) or, with
explicit muscle solvers, in a unit fails: its residuals are all FAILED_SCORE/√R, score
`FAILED_SCORE`, so it can never win.
"""

from __future__ import annotations

import functools
import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from functools import cache
from typing import NamedTuple

import numba
import numpy as np

from ..model.body import GROUND_OUTPUTS, body_work_size, ground_kinds, ground_outputs
from ..model.jit import njit
from ..solvers import fixed_step as fs
from ..solvers import step_loop
from ..solvers.rates import unit_excitation
from .parameters import PER_UNIT, RAMPS_PER_UNIT

#: Candidates simulated per compiled call (bounds the memory of the stored motions:
#: 64 × steps × state size numbers).
POPULATION_CHUNK = 64
#: Score of a candidate whose simulation failed or broke the stability guard, deg.
FAILED_SCORE = 1.0e4
PROFILE_SIZE = 2 + 3 * RAMPS_PER_UNIT
DEG = 180.0 / math.pi


@njit(cache=True, error_model="numpy")
def pack_profile(x, offset, initial_level, out):
    """Write the packed activation profile [a_0, n, (t_on, r, level) × n] of the ramps
    x[offset : offset + 9] (delay, duration, level each) into ``out``."""
    out[0] = initial_level
    out[1] = RAMPS_PER_UNIT
    t = 0.0
    for i in range(RAMPS_PER_UNIT):
        start = t + x[offset + 3 * i]
        out[2 + 3 * i] = start
        out[3 + 3 * i] = x[offset + 3 * i + 1]
        out[4 + 3 * i] = x[offset + 3 * i + 2]
        t = start + x[offset + 3 * i + 1]


#: What became of a candidate's run (`run_status`), and why a run that failed is unusable.
RUN_OK, RUN_NON_FINITE, RUN_DIVERGED, RUN_UNSTABLE_MUSCLE, RUN_UNSTABLE_CONTACT, RUN_NO_START = \
    range(6)
RUN_REASONS = ("", "non-finite state", "diverged", "step beyond explicit RK4's stability "
               "limit in a unit", "step beyond RK4's stability limit in a ground contact",
               "its model fields give no valid model or no static equilibrium to start from")


@njit(cache=True, error_model="numpy")
def run_status(stats, explicit_muscles, coupling):
    """RUN_OK, or the first reason the run with these loop ``stats`` is unusable:
    non-finite, diverged, a unit beyond the RK4 stability limit (only when the muscles are
    explicit), a ground contact beyond it (unless the packed ``coupling`` puts the body part
    on ROS2, implicit in the contacts)."""
    if stats[fs.STATUS] == fs.NON_FINITE:
        return RUN_NON_FINITE
    if stats[fs.STATUS] != fs.OK:
        return RUN_DIVERGED
    if explicit_muscles and stats[fs.WORST_RATIO] > fs.RK4_STABILITY_LIMIT:
        return RUN_UNSTABLE_MUSCLE
    if coupling[fs.BODY_SOLVER] != fs.ROS2 and stats[fs.CONTACT_RATIO] > fs.RK4_STABILITY_LIMIT:
        return RUN_UNSTABLE_CONTACT
    return RUN_OK


@njit(cache=True, error_model="numpy")
def sample_joint(states, step, times, joint, n, theta_out, omega_out):
    """Joint ``joint``'s q and q̇ at ``times`` (s from the start) from fixed-step states
    (columns q then q̇ of n joints): cubic Hermite in q (q̇ as its derivative), linear in q̇."""
    last = states.shape[0] - 1
    for k in range(times.shape[0]):
        s = times[k] / step
        i = min(int(s), last - 1)
        u = s - i
        th0, th1 = states[i, joint], states[i + 1, joint]
        om0, om1 = states[i, n + joint], states[i + 1, n + joint]
        u2 = u * u
        u3 = u2 * u
        theta_out[k] = ((2 * u3 - 3 * u2 + 1) * th0 + (u3 - 2 * u2 + u) * step * om0
                        + (-2 * u3 + 3 * u2) * th1 + (u3 - u2) * step * om1)
        omega_out[k] = (1.0 - u) * om0 + u * om1


@njit(cache=True, nogil=True, error_model="numpy")
def simulate_population(first, count, population, levels, kinds, system, run, ground_steps,
                        results):
    """Simulate the ``count`` rows from row ``first`` of ``population`` (m × 9U ramp vectors,
    `fitting.parameters`; fewer at its end) with the step loop of the kinds ``kinds``
    (`step_loop.StepKinds`) on ``system`` = the packed (segments, joints, units), unit u
    starting at ``levels[u]``; ``run`` = (packed coupling, y0, step (s), number of steps,
    whether the muscles are explicit, the body's `ground_kinds`). Fills ``results`` =
    (states, activations, outputs, status), per candidate j: ``states[j]`` (steps + 1 rows of y),
    ``status[j]`` (`run_status`), the profiles' values at the first
    ``activations.shape[2]`` steps into ``activations[j]`` (units × those steps; none for a
    fit, every step for an optimisation) and, for a body on the ground, its
    `GROUND_OUTPUTS` at the steps ``ground_steps`` (indices) into those columns of
    ``outputs[j]`` (4 × steps + 1). Releases the GIL: `run_population` runs one call per
    thread.

    The parameter arrays are copied per candidate: candidates run in parallel threads, and
    the step loops' reference counting on arrays shared between threads would contend
    (measured: the population scored 2.3x slower)."""
    seg, joints, units = system
    coupling, y0, step, n_steps, explicit_muscles, ground = run
    states, activations, outputs, status = results
    n = joints.shape[0]
    for j in range(first, min(first + count, population.shape[0])):
        seg_j, joints_j, units_j = seg.copy(), joints.copy(), units.copy()
        y0_j, coupling_j = y0.copy(), coupling.copy()
        profiles = np.zeros((levels.shape[0], PROFILE_SIZE))
        for u in range(levels.shape[0]):
            pack_profile(population[j], u * PER_UNIT, levels[u], profiles[u])
        stats = np.zeros(fs.STATS_SIZE)
        step_loop.run_step_loop(kinds, (seg_j, joints_j, units_j, profiles), y0_j, step, n_steps,
                         coupling_j, states[j], stats)
        flat = profiles.ravel()
        for u in range(levels.shape[0]):
            for k in range(activations.shape[2]):
                activations[j, u, k] = unit_excitation(k * step, flat, PROFILE_SIZE, u)
        status[j] = run_status(stats, explicit_muscles, coupling)
        if ground_steps.shape[0] > 0 and status[j] == RUN_OK:
            _ground_outputs_of_run(states[j], ground_steps, n, seg_j, joints_j.ravel(),
                                   outputs[j], ground)


@njit(cache=True, error_model="numpy")
def _ground_outputs_of_run(states, rows, n, seg, joints, out, ground):
    """`GROUND_OUTPUTS` at the ``rows`` of ``states`` into those columns of ``out``
    (4 × rows of states); ``ground`` the `BodyKinds` of a body on the ground, else None
    (`ground_kinds`: then nothing is compiled or done)."""
    if ground is not None:
        work = np.zeros(body_work_size(n, seg))
        torque = np.zeros(n)
        values = np.empty(4)
        for r in range(rows.shape[0]):
            k = rows[r]
            ground_outputs(states[k], n, seg, joints, torque, work, values, ground)
            for c in range(4):
                out[c, k] = values[c]


@cache
def _pool(threads: int) -> ThreadPoolExecutor:
    """The threads that run a population's candidates beside the calling thread (one pool
    per thread count, made on first use; a forked child process makes its own,
    `os.register_at_fork` below).

    Threads calling a compiled function that releases the GIL, rather than Numba's
    ``parallel=True``: the same speed within this machine's noise (64 candidates, best of 5
    in interleaved rounds at load 1.0–1.2: the jump 486–570 against 494–613 ms; the elbow
    29.0–37.4 against 29.2–37.7 ms) at 6 s less compile time per population kernel (the
    elbow fit's first evaluation 32.0 → 25.8 s, cold cache): a parallel function's outlined
    loop body is compiled and optimised again with everything it calls."""
    return ThreadPoolExecutor(threads, thread_name_prefix="torquesim-population")


os.register_at_fork(after_in_child=_pool.cache_clear)


def blas_on_one_thread(search):
    """Decorator: ``search`` runs with NumPy's linear algebra (BLAS, LAPACK) on one thread.
    A search calls them between its populations (CMA-ES's eigendecomposition, least
    squares' factorisations), and OpenBLAS's threads keep spinning for a while after each
    call: on 2 cores they took one from the population's threads (the squat jump's
    optimisation search 5.1 s against 3.2 s, the same optimum; its fit 6.3 s against 5.6 s)."""
    @functools.wraps(search)
    def on_one_thread(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"):
            return search(*args, **kwargs)
    return on_one_thread


def run_population(rows, kinds, coupling, y0, step: float, n_steps: int, arrays, levels,
                   explicit_muscles: bool, ground_steps, activation_steps: int = 0):
    """`simulate_population` of the ramp vectors ``rows`` (at most `POPULATION_CHUNK`) on the
    packed ``arrays`` (segments, joints, units) with the step loop of the kinds ``kinds``
    (`step_loop.StepKinds`), with its output arrays made here: returns
    (states, activations, ground outputs, status), the activations at the first
    ``activation_steps`` steps and the ground outputs at ``ground_steps`` (indices).
    The candidates run in Numba's number of threads (`numba.get_num_threads`, one in a Dask
    worker), each thread a contiguous block of them, as Numba's parallel loop scheduled
    them: this thread the first, the pool's (`_pool`) the others."""
    m, steps = rows.shape[0], n_steps + 1
    states = np.empty((m, steps, y0.size))
    activations = np.empty((m, levels.size, activation_steps))
    outputs = np.zeros((m, len(GROUND_OUTPUTS), steps if len(ground_steps) else 1))
    status = np.zeros(m, dtype=np.int64)
    ground_steps = np.asarray(ground_steps, dtype=np.int64)
    ground = ground_kinds(arrays[0], arrays[1].shape[0])
    threads = min(numba.get_num_threads(), m)
    block = -(-m // threads)  # candidates per thread, rounded up

    def run(thread):
        simulate_population(thread * block, block, rows, levels, kinds, tuple(arrays),
                            (coupling, y0, step, n_steps, explicit_muscles, ground),
                            ground_steps,
                            (states, activations, outputs, status))
    others = [_pool(threads - 1).submit(run, t) for t in range(1, threads)]
    run(0)  # this thread takes the first block instead of waiting
    for other in others:
        other.result()
    return states, activations, outputs, status


class OwnStart(NamedTuple):
    """What a candidate with model fields of its own starts from (`OwnStarts`)."""

    model: object  #: its `ChainModel` (the ramps those of the model it was made from)
    y0: np.ndarray  #: its initial state
    levels: np.ndarray  #: its units' initial activations
    arrays: tuple  #: its packed (segments, joints, units)


class OwnStarts:
    """The `OwnStart` of a candidate whose searched model fields (``space.fields``) differ
    from ``model``'s, called with a full parameter vector ``x``; None when its fields
    give no valid model or no static equilibrium (a `ModelError`). The start does not depend
    on the ramps, so it is made once per distinct set of field values (a Jacobian's ramp
    columns share one; the most recent `MAX_KEPT` are kept). The population's threads call
    it at once: one makes a start at a time (making one is Python, which runs one thread at
    a time anyway). Pickled (to Dask workers) without what it keeps."""

    MAX_KEPT = 256

    def __init__(self, space, model):
        self.space, self.model = space, model
        self.kept: dict[tuple, OwnStart | None] = {}
        self.lock = threading.Lock()

    def __getstate__(self) -> dict:
        return {"space": self.space, "model": self.model}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["space"], state["model"])

    def layout(self) -> OwnStart:
        """The start of ``model`` as it is: the sizes every candidate's start has (numeric
        fields change no state or unit count)."""
        return self(np.concatenate([np.zeros(self.space.size - len(self.space.fields)),
                                    self.space.field_values(self.model)]))

    def __call__(self, x) -> OwnStart | None:
        key = tuple(np.asarray(x, dtype=float)[x.size - len(self.space.fields):].tolist())
        with self.lock:
            return self._kept_or_made(key, x)

    def _kept_or_made(self, key: tuple, x) -> OwnStart | None:
        from ..errors import ModelError

        if key not in self.kept:
            if len(self.kept) >= self.MAX_KEPT:
                self.kept.pop(next(iter(self.kept)))
            try:
                model = self.space.with_fields(self.model, x)
                start = model.initial_state()
            except ModelError:
                self.kept[key] = None
            else:
                levels = np.array(start.levels, dtype=float)
                packed = model.pack(levels)
                self.kept[key] = OwnStart(model, start.state, levels,
                                          (packed.segments, packed.joints, packed.units))
        return self.kept[key]


def run_own_models(rows, own_starts, kinds, coupling, step: float, n_steps: int,
                   explicit_muscles: bool, ground_steps, activation_steps: int = 0):
    """`run_population` of candidates each with a model of its own (searched model fields):
    row j from its `OwnStart`, ``own_starts(rows[j])`` (`OwnStarts`; None: status
    `RUN_NO_START`), each candidate alone on one of the pool's threads (`_pool`), as many at
    once as `run_population` runs, so that making one candidate's start (Python) overlaps
    the others' runs (compiled, without the GIL). Returns `run_population`'s arrays and the
    starts; the same compiled kernel."""
    m, steps = rows.shape[0], n_steps + 1
    status = np.full(m, RUN_NO_START, dtype=np.int64)
    ground_steps = np.asarray(ground_steps, dtype=np.int64)
    layout = own_starts.layout()
    states = np.empty((m, steps, layout.y0.size))
    activations = np.empty((m, layout.levels.size, activation_steps))
    outputs = np.zeros((m, len(GROUND_OUTPUTS), steps if len(ground_steps) else 1))
    starts = [None] * m

    def run(j):
        starts[j] = start = own_starts(rows[j])
        if start is None:
            return
        ground = ground_kinds(start.arrays[0], start.arrays[1].shape[0])
        simulate_population(0, 1, rows[j:j + 1], start.levels, kinds, tuple(start.arrays),
                            (coupling, start.y0, step, n_steps, explicit_muscles, ground),
                            ground_steps, (states[j:j + 1], activations[j:j + 1],
                                           outputs[j:j + 1], status[j:j + 1]))
    list(_pool(min(numba.get_num_threads(), m)).map(run, range(m)))  # raises what a run raised
    return states, activations, outputs, status, starts


def steps_around(times, step: float, n_steps: int) -> np.ndarray:
    """The step indices `sample_joint` and `sample_outputs` read at ``times`` (s from the
    start): the steps before and after each time."""
    below = np.minimum((np.asarray(times) / step).astype(np.int64), n_steps - 1)
    return np.unique(np.concatenate([below, below + 1]))


@njit(cache=True, error_model="numpy")
def sample_outputs(outputs, step, times, channels, out):
    """The ground outputs ``channels`` (`GROUND_OUTPUTS` indices, rows of ``outputs``, one
    column per step) at ``times`` (s from the start), linear between the steps around each
    time, into the rows of ``out``."""
    last = outputs.shape[1] - 1
    for k in range(times.shape[0]):
        s = times[k] / step
        i = min(int(s), last - 1)
        u = s - i
        for r in range(channels.shape[0]):
            c = channels[r]
            out[r, k] = (1.0 - u) * outputs[c, i] + u * outputs[c, i + 1]


class ResidualTerms(NamedTuple):
    """What a fit's residual vector compares (module docstring), packed once per fit for the
    compiled kernels: the target ``times`` (s, from the start); the ``scored`` coordinates'
    indices; their target ``angles`` and ``speeds`` (rad, rad/s; a row per scored coordinate,
    a column per time) and ``weights`` (summing to 1); the ground-output ``channels``
    (indices into `GROUND_OUTPUTS`), their target ``channel_values`` and ``channel_scales``
    s_c; each unit's rest level ``rests``; the weights w_ω, w_end and w_a."""

    times: np.ndarray
    scored: np.ndarray
    angles: np.ndarray
    speeds: np.ndarray
    weights: np.ndarray
    channels: np.ndarray
    channel_values: np.ndarray
    channel_scales: np.ndarray
    rests: np.ndarray
    weight_velocity: float
    weight_end: float
    weight_effort: float


@njit(cache=True, error_model="numpy")
def fill_residual(theta, omega, channel_values, profiles, terms, out):
    """The residual vector of one simulated candidate (module docstring) into ``out``: its
    scored coordinates' q and q̇ (``theta``, ``omega``) and ground outputs
    (``channel_values``) at the target times, its packed activation ``profiles``, compared
    by the `ResidualTerms` ``terms``."""
    n_rows, n_samples = theta.shape
    target_theta, target_omega = terms.angles, terms.speeds
    weight_velocity, weight_end = terms.weight_velocity, terms.weight_end
    i = 0
    scale = 1.0 / math.sqrt(n_samples)
    for r in range(n_rows):
        w = math.sqrt(terms.weights[r]) * DEG
        for k in range(n_samples):
            out[i] = w * scale * (theta[r, k] - target_theta[r, k])
            i += 1
        if weight_velocity > 0.0:
            for k in range(n_samples):
                out[i] = weight_velocity * w * scale * (omega[r, k] - target_omega[r, k])
                i += 1
        if weight_end > 0.0:
            last = n_samples - 1
            out[i] = weight_end * w * (theta[r, last] - target_theta[r, last])
            out[i + 1] = weight_end * w * (omega[r, last] - target_omega[r, last])
            i += 2
    if terms.weight_effort > 0.0:
        w = math.sqrt(terms.weight_effort) * scale
        flat = profiles.ravel()
        for u in range(terms.rests.shape[0]):
            for k in range(n_samples):
                out[i] = w * max(unit_excitation(terms.times[k], flat, PROFILE_SIZE, u)
                                 - terms.rests[u], 0.0)
                i += 1
    for r in range(channel_values.shape[0]):
        w = terms.channel_scales[r] * scale
        for k in range(n_samples):
            out[i] = w * (channel_values[r, k] - terms.channel_values[r, k])
            i += 1


def residual_size(n_rows: int, n_samples: int, n_units: int, weight_velocity: float,
                  weight_end: float, weight_effort: float, n_channels: int = 0) -> int:
    """Length of the residual vector (module docstring)."""
    per_row = n_samples * (1 + (weight_velocity > 0)) + 2 * (weight_end > 0)
    return n_rows * per_row + (n_units * n_samples if weight_effort > 0 else 0) \
        + n_channels * n_samples


@njit(cache=True, error_model="numpy")
def population_residuals(population, levels, states, outputs, status, step, n, terms,
                         residuals, failed):
    """Residuals (rows of ``residuals``) and failure flags of every row of ``population``
    (m × 9U) from its run by `simulate_population` (``states`` of a body of ``n``
    coordinates at ``step`` s, ground ``outputs`` and ``status``), compared by the
    `ResidualTerms` ``terms``: q and q̇ of the
    scored coordinates at the target times by `sample_joint`, the ground output channels by
    `sample_outputs`, the activations from the candidate's ramps (`pack_profile`, unit u
    starting at ``levels[u]``). One thread: sampling costs little beside the runs, and a
    parallel kernel would add a parallel compilation (5 s) to a cold first fit."""
    n_rows, n_samples = terms.angles.shape
    failed_value = FAILED_SCORE / math.sqrt(residuals.shape[1])
    for j in range(population.shape[0]):
        if status[j] != RUN_OK:
            residuals[j, :] = failed_value
            failed[j] = True
            continue
        theta = np.empty((n_rows, n_samples))
        omega = np.empty((n_rows, n_samples))
        for r in range(n_rows):
            sample_joint(states[j], step, terms.times, terms.scored[r], n, theta[r], omega[r])
        values = np.empty((terms.channels.shape[0], n_samples))
        sample_outputs(outputs[j], step, terms.times, terms.channels, values)
        profiles = np.zeros((levels.shape[0], PROFILE_SIZE))
        for u in range(levels.shape[0]):
            pack_profile(population[j], u * PER_UNIT, levels[u], profiles[u])
        fill_residual(theta, omega, values, profiles, terms, residuals[j])
        failed[j] = False
