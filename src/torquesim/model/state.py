"""The state vector's layout, in one place: y = (q_1…q_n, q̇_1…q̇_n, the units' own states).

Every kernel, result and file reads positions through these names, never through literal
offsets. A Hill unit (this model) has one state of its own, its CE angle θ_cc (rad); a unit
kind with more states (activation dynamics, say) changes `UNIT_STATE_WIDTH` and the unit's
rate, not the kernels' indexing.
"""

from __future__ import annotations

from dataclasses import dataclass

from numba import njit

#: States per unit: θ_cc.
UNIT_STATE_WIDTH = 1


@njit(cache=True, inline="always")
def unit_states_start(n):
    """Index in y of the first unit state on a chain of ``n`` joints (after q and q̇)."""
    return 2 * n


@njit(cache=True, inline="always")
def unit_state(n, u):
    """Index in y of unit ``u``'s CE angle θ_cc on a chain of ``n`` joints."""
    return 2 * n + u * UNIT_STATE_WIDTH


@dataclass(frozen=True)
class StateLayout:
    """Where each quantity sits in the state vector y of a chain of ``n_joints`` joints and
    ``n_units`` units (`ChainModel.layout`)."""

    n_joints: int
    n_units: int

    @property
    def angles(self) -> slice:
        """q, rad (joint angles)."""
        return slice(0, self.n_joints)

    @property
    def speeds(self) -> slice:
        """q̇, rad/s (joint angular velocities)."""
        return slice(self.n_joints, 2 * self.n_joints)

    @property
    def unit_states(self) -> slice:
        """Every unit's own states (θ_cc, rad), unit by unit."""
        return slice(2 * self.n_joints, self.size)

    def unit_state(self, u: int) -> int:
        """Index of unit ``u``'s θ_cc."""
        return 2 * self.n_joints + u * UNIT_STATE_WIDTH

    @property
    def size(self) -> int:
        return 2 * self.n_joints + self.n_units * UNIT_STATE_WIDTH
