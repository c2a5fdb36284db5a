"""The packed row of one unit, as the compiled solvers read it: the `TorqueGeneratorUnit`
array, then where the unit acts and where its own states sit (`ChainModel.unit_array`)."""

from __future__ import annotations

from .torque_generator import UNIT_ARRAY_SIZE

#: Index of the joint the unit acts on.
UNIT_JOINT = UNIT_ARRAY_SIZE
#: +1 flexor, −1 extensor.
UNIT_DIRECTION = UNIT_ARRAY_SIZE + 1
#: Offset of the unit's first state (θ_cc) from the first unit state of y (`model.state`).
UNIT_STATE_OFFSET = UNIT_ARRAY_SIZE + 2
#: τ_act and τ_deact of its activation dynamics, s; 0 when it has none (a = e(t)).
UNIT_ACTIVATION_TIME = UNIT_ARRAY_SIZE + 3
UNIT_DEACTIVATION_TIME = UNIT_ARRAY_SIZE + 4
UNIT_ROW_SIZE = UNIT_ARRAY_SIZE + 5
