import os

# The suite runs in several processes (pytest-xdist), so each process's BLAS gets one thread:
# OpenBLAS's default of one thread per core, in two processes on two cores, spins threads
# against each other (measured: the strength tests 62 s under `-n 2`, 13 s with one thread;
# scikit-learn's suite limits its xdist workers the same way). Set before NumPy loads BLAS,
# here and, inherited, in the worker processes started after this file is read.
for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import settings  # noqa: E402

import torquesim as ts  # noqa: E402

# No test depends on the clock: hypothesis's per-example deadline (200 ms) failed three
# property tests on a loaded machine, where an example's first call compiles.
settings.register_profile("no-deadline", deadline=None)
settings.load_profile("no-deadline")


@pytest.fixture(scope="session")
def model():
    return ts.default_model()


@pytest.fixture(scope="session")
def reference(model):
    """Radau at rtol 1e-11 on the 1 ms grid: 'truth' for the default curl."""
    return ts.simulate(model, "reference", rtol=1e-11, atol=1e-13)


def max_angle_error(result, reference) -> float:
    """Max |q − q_ref| (rad) over the joints at the times both grids share (the result's step
    and the reference's output step are multiples of one another)."""
    ratio = (reference.time[1] - reference.time[0]) / result.step
    if ratio >= 1:
        k = int(round(ratio))
        return float(np.max(np.abs(result.q[::k] - reference.q)))
    k = int(round(1 / ratio))
    return float(np.max(np.abs(result.q - reference.q[::k])))


def chain_energy(result):
    """Kinetic + gravity + SE + end-stop energy (J) of a chain run, written independently of
    the solver's mass matrix: every segment and point load as a rigid body whose centre moves
    with v = Σ_{j<k} L_j·φ̇_j·e(φ_j) + r·φ̇_k·e(φ_k), e(φ) = (cos φ, sin φ), at height
    −(Σ_{j<k} L_j·cos φ_j + r·cos φ_k)."""
    from torquesim.model.body import passive_energy

    m = result.model
    phi = m.base_angle + np.cumsum(result.q, axis=1)
    phid = np.cumsum(result.qd, axis=1)
    energy = np.zeros(result.time.size)
    base_v = np.zeros((result.time.size, 2))
    base_h = np.zeros(result.time.size)
    for k, seg in enumerate(m.segments):
        e = np.stack([np.cos(phi[:, k]), np.sin(phi[:, k])], axis=1)
        bodies = [(seg.mass, seg.com_distance, seg.inertia_about_joint
                   - seg.mass * seg.com_distance**2)]
        bodies += [(ld.mass, ld.distance, ld.inertia) for ld in seg.loads]
        for mass, r, own in bodies:
            v = base_v + r * phid[:, k:k + 1] * e
            height = base_h - r * np.cos(phi[:, k])
            energy += 0.5 * mass * np.sum(v**2, axis=1) + 0.5 * own * phid[:, k]**2 \
                + mass * m.gravity * height
        base_v = base_v + seg.length * phid[:, k:k + 1] * e
        base_h = base_h - seg.length * np.cos(phi[:, k])
    for j, joint in enumerate(m.joints):
        stops = joint.endstop_array()
        energy += np.array([passive_energy(x, stops) for x in result.q[:, j]])
    for u, unit in enumerate(m.units):
        q = result.q[:, m.joint_index(unit.joint)]  # ψ = q_j + d·r·q_j2 for a two-joint unit
        if unit.second_joint is not None:
            q = q + unit.direction * unit.second_arm * result.q[:, m.joint_index(unit.second_joint)]
        stretch = unit.direction * (result.theta_cc[:, u] - q)
        energy += 0.5 * unit.parameters.se_stiffness * np.maximum(stretch, 0.0) ** 2
    return energy


def ce_power(result):
    """Σ T_u·ω_cc,u (W): the power the contractile elements deliver (concentric positive)."""
    c = result.columns()
    return sum(c[f"torque_{u.name}"] * c[f"omega_cc_{u.name}"] for u in result.model.units)


#: Radau references of `measured_order`, by case: each case's is solved once per process,
#: not once per technique (it was 30 s of the suite's time).
_ORDER_REFERENCES: dict[tuple[str, bytes], object] = {}


def order_reference(model, y0):
    """Radau at rtol 1e-12 on a 10 ms grid from state ``y0``, solved once per process."""
    key = (repr(model), np.asarray(y0, dtype=float).tobytes())
    if key not in _ORDER_REFERENCES:
        _ORDER_REFERENCES[key] = ts.simulate(model, "reference", rtol=1e-12, atol=1e-14,
                                             initial_state=y0, output_step=0.01)
    return _ORDER_REFERENCES[key]


def measured_order(case, method, coupling, steps) -> float:
    """Slope of log(max |q − q_ref|) against log(h) over ``steps`` on ``case`` = (model,
    initial state), against Radau at rtol 1e-12 on a 10 ms grid (the steps divide it). The
    runs skip simulate's error estimate and step advice, which do not change q."""
    from scipy.stats import linregress

    model, y0 = case
    ref = order_reference(model, y0)
    errors = []
    for h in steps:
        r = ts.simulate(model, method, h, initial_state=y0, coupling=coupling, tolerance=None,
                        advise=False)
        errors.append(np.max(np.abs(r.q[::int(round(0.01 / h))] - ref.q)))
    return linregress(np.log(steps), np.log(errors)).slope


def activation_dynamics_case(extensor_dynamics: bool = True):
    """The smooth elbow case (`torquesim.study.smooth_case`) with first-order activation
    dynamics on the flexor (and, by default, the extensor): (chain model, initial state).

    The excitations stay constant (flexor 0.6, extensor 0.3); the flexor's activation starts
    at 0.65 and decays towards 0.6 (deactivation branch), the extensor's at 0.29 and rises
    towards 0.3 (activation branch), so neither crosses its excitation, both CEs keep their
    direction (flexor shortening, extensor lengthening) and the motion is smooth."""
    import dataclasses

    from torquesim.study import smooth_case

    elbow, y_plain = smooth_case()
    plain = elbow.to_chain()
    model = plain.replace(units=tuple(
        dataclasses.replace(u, activation_dynamics=ts.ActivationDynamics())
        if u.direction == 1 or extensor_dynamics else u for u in plain.units))
    layout = model.layout
    y0 = np.zeros(layout.size)
    y0[:2] = y_plain[:2]
    for u, start in enumerate((0.65, 0.29)):
        y0[layout.unit_state(u)] = y_plain[plain.layout.unit_state(u)]
        if layout.activation_state(u) is not None:
            y0[layout.activation_state(u)] = start
    return model, y0


def fit_target(argv, monkeypatch):
    """The target `torquesim fit ARGV` builds (channels and all), the fit stopped where its
    search would start."""
    import torquesim.fitting.outputs as outputs
    from torquesim.cli import main

    seen = {}

    class Reached(Exception):
        pass

    def stop(problem, *_, **__):
        seen["target"] = problem.target
        raise Reached

    monkeypatch.setattr(outputs, "fit_and_write", stop)
    with pytest.raises(Reached):
        main(["fit", *argv])
    return seen["target"]


def write_angle_csv(path, time, model, angles_deg):
    """A CSV target: ``time`` and each joint's angle (degrees) under the joint's name."""
    names = [j.name for j in model.joints]
    table = np.column_stack([time, *angles_deg])
    path.write_text("time," + ",".join(names) + "\n"
                    + "\n".join(",".join(f"{v:.6f}" for v in row) for row in table) + "\n")
    return path
