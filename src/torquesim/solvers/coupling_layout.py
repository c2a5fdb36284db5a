"""Layout of the packed coupling array the partitioned step loop reads (written by
`Coupling.to_array`), without Numba, so that the technique registry can be read by the
command line without loading the compiler."""

ORDER, PREDICTOR, MUSCLE_SUBSTEPS, ITERATIONS, TOLERANCE, MUSCLE_SOLVER = range(6)
COUPLING_SIZE = 6
#: Values of ORDER, PREDICTOR and MUSCLE_SOLVER.
JACOBI, BODY_FIRST, MUSCLES_FIRST, EVERY_STAGE = 0, 1, 2, 3
HOLD, LINEAR = 0, 1
EXPLICIT_RK4, SDIRK2 = 0, 1
