"""Layout of the packed coupling array the partitioned step loop reads (written by
`Coupling.to_array`), without Numba, so that the technique registry can be read by the
command line without loading the compiler."""

ORDER, PREDICTOR, MUSCLE_SUBSTEPS, ITERATIONS, TOLERANCE, MUSCLE_SOLVER, BODY_SOLVER = range(7)
COUPLING_SIZE = 7
#: Values of ORDER, PREDICTOR, MUSCLE_SOLVER and BODY_SOLVER.
JACOBI, BODY_FIRST, MUSCLES_FIRST, EVERY_STAGE = 0, 1, 2, 3
HOLD, LINEAR = 0, 1
EXPLICIT_RK4, SDIRK2, ROS2 = 0, 1, 2
