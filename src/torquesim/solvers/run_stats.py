"""Layout of the stats array the step loops fill (`fixed_step.new_stats`), and the
stability guard's update, in one place for the loops and the right-hand side
(`rates.system_rates`)."""

from __future__ import annotations

from numba import njit

# Indices of the stats array returned by the loops.
# NEWTON_ITERATIONS: residual evaluations of the implicit unit equations (each one a Newton
# iteration with its scalar linear solve, or the bracket check); IMPLICIT_SOLVES: implicit stage
# equations solved. COUPLING_*: the coupling-error indicator of the partitioned loop (see
# rk4_partitioned): Σ over steps of max_j |δτ_j|·h (N·m·s), its largest term's |δτ| (N·m) and
# time (s), and Σ over steps of max_j |δq_j| (rad).
# CONTACT_*: the stability guard of the ground contacts (always explicit, in the body part):
# the largest step/τ of a contact (`contact_time_constant`), its time and contact index.
STATUS, STEPS, NFEV_BODY, NFEV_MUSCLE, WORST_RATIO, WORST_TIME, WORST_UNIT, SWEEPS, \
    NEWTON_ITERATIONS, IMPLICIT_SOLVES, COUPLING_TORQUE, COUPLING_TORQUE_MAX, COUPLING_TIME, \
    COUPLING_ANGLE, CONTACT_RATIO, CONTACT_TIME, CONTACT_INDEX = range(17)
STATS_SIZE = 17
# Status codes. DIVERGED: the state left the physically possible range (a joint more than a
# full turn beyond its end stops, or faster than its speed limit, ChainModel.speed_limits).
OK, NON_FINITE, DIVERGED = 0, 1, 2


@njit(cache=True, error_model="numpy", inline="always")
def record_stiffness(stats, t, ratio, u):
    """Update the largest step/τ seen (the stability guard) with unit u's ratio at time t."""
    if ratio > stats[WORST_RATIO]:
        stats[WORST_RATIO] = ratio
        stats[WORST_TIME] = t
        stats[WORST_UNIT] = u
