"""The state vector's layout, in one place: y = (coordinates, their speeds, the units' own
states), the coordinates being the joint angles q_1…q_n, preceded on a free base by the
position (x, y) of the first segment's proximal point.

Every kernel, result and file reads positions through these names, never through literal
offsets. Each unit kind has its own state width (`UNIT_STATE_WIDTHS`): a Hill unit has one
state, its CE angle θ_cc (rad); a Hill unit with activation dynamics
(`ActivationDynamics`) has two, θ_cc and its activation a. A unit's states sit together, in
unit order, and its packed row records where they start (`UNIT_STATE_OFFSET`), so the compiled
loops find them without knowing the other units' kinds.
"""

from __future__ import annotations

from dataclasses import dataclass

from .jit import njit
from .unit_row import UNIT_ACTIVATION_TIME, UNIT_ROW_SIZE, UNIT_STATE_OFFSET

#: States per unit kind: θ_cc; θ_cc and a.
UNIT_STATE_WIDTHS = {"hill": 1, "hill_with_activation_dynamics": 2}


@njit(cache=True, inline="always")
def unit_states_start(n):
    """Index in y of the first unit state of a body of ``n`` coordinates (after them and
    their speeds)."""
    return 2 * n


@njit(cache=True, inline="always")
def unit_state(n, units, u):
    """Index in y of unit ``u``'s CE angle θ_cc on a body of ``n`` coordinates (``units``:
    the flat packed unit rows)."""
    return 2 * n + int(units[u * UNIT_ROW_SIZE + UNIT_STATE_OFFSET])


@njit(cache=True, inline="always")
def has_activation_state(units, u):
    """Whether unit ``u`` has activation dynamics: its activation a is then the state after
    its θ_cc, at ``unit_state(n, units, u) + 1``."""
    return units[u * UNIT_ROW_SIZE + UNIT_ACTIVATION_TIME] > 0.0


@dataclass(frozen=True)
class StateLayout:
    """Where each quantity sits in the state vector y of a body of ``n_joints`` joints (and
    ``n_base`` base coordinates: 2 on a free base) whose units have ``unit_widths`` states
    each (`ChainModel.layout`)."""

    n_joints: int
    unit_widths: tuple[int, ...]
    n_base: int = 0

    @property
    def n_units(self) -> int:
        return len(self.unit_widths)

    @property
    def n_coordinates(self) -> int:
        return self.n_base + self.n_joints

    @property
    def coordinates(self) -> slice:
        """The base's coordinates and the joint angles."""
        return slice(0, self.n_coordinates)

    @property
    def coordinate_speeds(self) -> slice:
        return slice(self.n_coordinates, 2 * self.n_coordinates)

    @property
    def angles(self) -> slice:
        """q, rad (joint angles)."""
        return slice(self.n_base, self.n_coordinates)

    @property
    def speeds(self) -> slice:
        """q̇, rad/s (joint angular velocities)."""
        return slice(self.n_coordinates + self.n_base, 2 * self.n_coordinates)

    def unit_offset(self, u: int) -> int:
        """Offset of unit ``u``'s first state from the first unit state."""
        return sum(self.unit_widths[:u])

    def unit_state(self, u: int) -> int:
        """Index of unit ``u``'s θ_cc."""
        return 2 * self.n_coordinates + self.unit_offset(u)

    def activation_state(self, u: int) -> int | None:
        """Index of unit ``u``'s activation a, or None when a is its profile (no dynamics)."""
        return self.unit_state(u) + 1 if self.unit_widths[u] > 1 else None

    @property
    def theta_cc(self) -> list[int]:
        """Index of every unit's θ_cc, in unit order."""
        return [self.unit_state(u) for u in range(self.n_units)]

    @property
    def size(self) -> int:
        return 2 * self.n_coordinates + sum(self.unit_widths)
