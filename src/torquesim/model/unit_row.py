"""The packed row of one unit, as the compiled solvers read it: the `TorqueGeneratorUnit`
array, then where the unit acts and where its own states sit (`ChainModel.unit_array`).

Where the unit acts is its row of the moment-arm matrix, held sparse: a unit spans one joint
or two adjacent ones. At its joint its torque acts with arm δ = ±1 (its direction), at its
second joint with the signed arm r (0 and the first joint again for a one-joint unit), so the
joint torques are τ_j = δ·T, τ_j2 = r·T and the unit's angle is ψ = q_j + δ·r·q_j2
(`torquesim.solvers.rates.unit_angle`)."""

from __future__ import annotations

from .torque_generator import UNIT_ARRAY_SIZE

#: Index of the (first) joint the unit acts on.
UNIT_JOINT = UNIT_ARRAY_SIZE
#: +1 flexor, −1 extensor: the unit's moment arm at that joint.
UNIT_DIRECTION = UNIT_ARRAY_SIZE + 1
#: Offset of the unit's first state (θ_cc) from the first unit state of y (`model.state`).
UNIT_STATE_OFFSET = UNIT_ARRAY_SIZE + 2
#: τ_act and τ_deact of its activation dynamics, s; 0 when it has none (a = e(t)).
UNIT_ACTIVATION_TIME = UNIT_ARRAY_SIZE + 3
UNIT_DEACTIVATION_TIME = UNIT_ARRAY_SIZE + 4
#: Index of its second joint (a two-joint unit), else `UNIT_JOINT`'s again.
UNIT_SECOND_JOINT = UNIT_ARRAY_SIZE + 5
#: Its signed moment arm r at the second joint, relative to the first (0: one joint).
UNIT_SECOND_ARM = UNIT_ARRAY_SIZE + 6
UNIT_ROW_SIZE = UNIT_ARRAY_SIZE + 7
