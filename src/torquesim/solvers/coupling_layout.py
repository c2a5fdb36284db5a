"""Layout of the packed coupling array the partitioned step loop reads (written by
`Coupling.to_array`), without Numba, so that the technique registry can be read by the
command line without loading the compiler."""

ORDER, PREDICTOR, MUSCLE_SUBSTEPS, ITERATIONS, TOLERANCE, MUSCLE_SOLVER, BODY_SOLVER = range(7)
#: The error-controlled loop's settings (`torquesim.solvers.error_control`; zero in every
#: fixed-step run): the angle tolerance (rad), the relative tolerance and the largest step (s).
ABSOLUTE_TOLERANCE, RELATIVE_TOLERANCE, MAX_STEP = 7, 8, 9
COUPLING_SIZE = 10
#: Values of ORDER, PREDICTOR, MUSCLE_SOLVER and BODY_SOLVER.
JACOBI, BODY_FIRST, MUSCLES_FIRST, EVERY_STAGE = 0, 1, 2, 3
HOLD, LINEAR = 0, 1
EXPLICIT_RK4, SDIRK2, ROS2 = 0, 1, 2
