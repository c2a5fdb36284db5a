"""Chains: dynamics against an independent engine, energy, equilibrium start, presets,
orders, the elbow unchanged, and the bad-input catalogue of chain files."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import torquesim as ts
from torquesim.model.body import (
    body_work_size,
    joint_accelerations,
    single_segment_acceleration,
)
from torquesim.solvers.rates import chain_derivative
from torquesim.study import smooth_chain_case

from .conftest import chain_energy

PRESETS = ("elbow-curl", "knee-extension", "arm-raise")


def _passive_unit(joint: str, direction: int, name: str) -> ts.Unit:
    """A unit on ``joint`` whose SE never pulls in these tests (its CE angle is set so the SE
    stays slack): the chain is then driven by the prescribed torques only."""
    return ts.Unit(name, joint, direction, ts.TorqueGeneratorUnit.flexor_default(),
                   ts.ActivationProfile(0.0))


def chain(n: int, endstops: float = 0.0, base_angle: float = 0.3) -> ts.ChainModel:
    """An n-segment test chain with unequal segments and a point load on each."""
    segments, joints, units = [], [], []
    for k in range(n):
        mass, com, length = 2.0 - 0.4 * k, 0.15 + 0.03 * k, 0.35 - 0.05 * k
        segments.append(ts.Segment(f"s{k}", mass, com, mass * com**2 + 0.02 + 0.01 * k, length,
                                   (ts.PointLoad(f"w{k}", 0.5 + k, 0.8 * length, 0.003),)))
        joints.append(ts.Joint(f"j{k}", initial_angle=0.2 + 0.3 * k, endstop_torque=endstops,
                               endstop_lower_angle=-1.0, endstop_upper_angle=1.5))
        units.append(ts.Unit(f"u{k}", f"j{k}", 1, ts.TorqueGeneratorUnit.flexor_default(),
                             ts.ActivationProfile(None)))
    return ts.ChainModel("test_chain", tuple(segments), tuple(joints), tuple(units),
                         base_angle=base_angle, duration=1.0)


def prescribed_torques(t: float, n: int) -> np.ndarray:
    return np.array([3.0 * math.sin(2.0 * t + k) + 1.0 * k for k in range(n)])


def torquesim_rhs(model, torques=prescribed_torques):
    seg = model.segment_array()
    joints = model.joint_array().ravel()
    n = model.n_joints
    work = np.empty(body_work_size(n, seg))

    def rhs(t, y):
        y = np.ascontiguousarray(y)
        joint_accelerations(y, n, torques(t, n), seg, joints, work)
        return np.concatenate([y[n:], work[n * n: n * n + n]])

    return rhs


def sympy_rhs(model):
    """The same chain built independently with sympy.physics.mechanics (Kane's method):
    frames rotated by the relative angles, rigid bodies and particles at their points, gravity
    on every mass, each joint torque acting on its segment and, reversed, on the one before."""
    import sympy as sp
    import sympy.physics.mechanics as me

    n = model.n_joints
    q = me.dynamicsymbols(f"q0:{n}")
    u = me.dynamicsymbols(f"u0:{n}")
    tau = sp.symbols(f"tau0:{n}")
    g = sp.Float(model.gravity)
    ground = me.ReferenceFrame("N")
    joint_point = me.Point("O")
    joint_point.set_vel(ground, 0)
    frames, bodies, loads = [], [], []
    previous = ground
    for k, seg in enumerate(model.segments):
        angle = q[k] + (model.base_angle if k == 0 else 0)
        frame = previous.orientnew(f"A{k}", "Axis", [angle, ground.z])
        frame.set_ang_vel(ground, sum(u[: k + 1]) * ground.z)
        axis = -frame.y  # the segment hangs along -y at zero angle
        pieces = [(seg.mass, seg.com_distance, seg.inertia_about_joint
                   - seg.mass * seg.com_distance**2, f"c{k}")]
        pieces += [(ld.mass, ld.distance, ld.inertia, f"l{k}{ld.name}") for ld in seg.loads]
        for mass, r, own, name in pieces:
            point = joint_point.locatenew(name, r * axis)
            point.v2pt_theory(joint_point, ground, frame)
            inertia = (me.inertia(frame, 0, 0, own), point)
            bodies.append(me.RigidBody(name, point, frame, mass, inertia))
            loads.append((point, -mass * g * ground.y))
        loads.append((frame, tau[k] * ground.z))
        if k > 0:
            loads.append((previous, -tau[k] * ground.z))
        next_point = joint_point.locatenew(f"J{k + 1}", seg.length * axis)
        next_point.v2pt_theory(joint_point, ground, frame)
        joint_point, previous = next_point, frame
        frames.append(frame)
    kane = me.KanesMethod(ground, q_ind=q, u_ind=u,
                          kd_eqs=[q[k].diff() - u[k] for k in range(n)])
    kane.kanes_equations(bodies, loads)
    mass = sp.lambdify([q, u, tau], kane.mass_matrix_full, "numpy")
    forcing = sp.lambdify([q, u, tau], kane.forcing_full, "numpy")

    def rhs(t, y):
        args = (y[:n], y[n:], prescribed_torques(t, n))
        return np.linalg.solve(mass(*args), forcing(*args)).ravel()

    return rhs


@pytest.mark.slow
@pytest.mark.parametrize("n", [2, 3])
def test_chain_dynamics_agree_with_sympy_mechanics(n):
    model = chain(n)
    y0 = np.concatenate([[j.initial_angle for j in model.joints], 0.5 * np.ones(n)])
    runs = [solve_ivp(rhs, (0.0, 1.0), y0, method="DOP853", rtol=1e-12, atol=1e-12,
                      t_eval=np.linspace(0.0, 1.0, 101))
            for rhs in (torquesim_rhs(model), sympy_rhs(model))]
    assert np.ptp(runs[0].y[:n], axis=1).min() > 0.1  # the chain really moves
    assert np.max(np.abs(runs[0].y[:n] - runs[1].y[:n])) < 1e-8


def test_one_segment_division_equals_the_general_solve():
    model = chain(1)
    seg, joints = model.segment_array(), model.joint_array().ravel()
    work = np.empty(body_work_size(1, seg))
    for q, qd, torque in [(0.3, 1.0, 2.0), (-0.5, -2.0, -7.5), (1.4, 0.0, 0.0)]:
        y = np.array([q, qd, 0.0])
        joint_accelerations(y, 1, np.array([torque]), seg, joints, work)
        assert work[1] == single_segment_acceleration(q, torque, seg, joints)


@pytest.mark.parametrize("n", [2, 3])
def test_passive_chain_conserves_energy(n):
    """No muscle torque, conservative end stops: RK4 at 0.1 ms keeps the energy (written
    independently of the solver, tests/conftest.py) to 1e-9 relative over 1 s."""
    model = chain(n, endstops=1.0)
    rhs = torquesim_rhs(model, lambda t, n: np.zeros(n))
    h, y = 1e-4, np.concatenate([[j.initial_angle for j in model.joints], np.zeros(n)])
    states = [y]
    for _ in range(10000):
        k1 = rhs(0, y)
        k2 = rhs(0, y + 0.5 * h * k1)
        k3 = rhs(0, y + 0.5 * h * k2)
        k4 = rhs(0, y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        states.append(y)
    states = np.array(states)

    class Run:  # the fields chain_energy reads, with the units' SEs slack
        pass

    run = Run()
    run.model, run.time = model, np.arange(states.shape[0]) * h
    run.q, run.qd = states[:, :n], states[:, n:]
    run.theta_cc = states[:, :n] - 1.0  # flexor stretch θ_cc − q < 0: no SE energy
    energy = chain_energy(run)
    assert np.ptp(run.q[:, -1]) > 0.3  # it swings
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * np.max(np.abs(energy))


def test_prescribed_torques_override_gravity_sign():
    """Sanity of the sign conventions: a chain hanging straight with a flexion torque at
    the base accelerates in flexion at the base joint."""
    model = chain(2, base_angle=0.0)
    y = np.zeros(4)
    work = np.empty(body_work_size(2, model.segment_array()))
    joint_accelerations(y, 2, np.array([5.0, 0.0]), model.segment_array(),
                        model.joint_array().ravel(), work)
    assert work[4] > 0.0 and work[5] < 0.0  # the distal joint lags behind (relative angle)


@pytest.mark.parametrize("name", PRESETS)
def test_presets_start_at_rest(name):
    model = ts.load_model(f"builtin:{name}")
    start = model.initial_state()
    rates = chain_derivative(0.0, start.state, *model.pack())
    n = model.n_joints
    assert np.all(rates[:n] == 0.0)
    assert np.max(np.abs(rates[n:2 * n])) < 1e-9  # |q̈(0)|
    assert np.max(np.abs(rates[2 * n:])) < 1e-9  # every CE isometric
    assert np.all((0.0 <= start.levels) & (start.levels <= 1.0))


@pytest.mark.parametrize("name", ["knee-extension", "arm-raise"])
def test_preset_methods_agree_with_the_reference(name):
    model = ts.load_model(f"builtin:{name}")
    reference = ts.simulate(model, "reference", rtol=1e-10, atol=1e-12)

    def error(method, step, coupling=None):
        r = ts.simulate(model, method, step, coupling=coupling)
        k = int(round(1e-3 / step))
        return float(np.max(np.abs(r.q[::k] - reference.q)))

    assert error("monolithic", 1e-4) < 1e-6
    assert error("imex", 5e-4) < 2e-3
    assert error("partitioned", 5e-5, ts.Coupling(predictor="linear")) < 1e-3
    assert error("partitioned", 5e-5, ts.Coupling(order="every-stage")) < 1e-6
    first, half = error("partitioned", 2.5e-5), error("partitioned", 1.25e-5)
    assert 1.5 < first / half < 2.4  # plain partitioned converges, at first order
    # an explicit method of another family agrees with the reference (Radau); Radau at a
    # looser tolerance only once (on the arm it costs half the reference again)
    for scipy_method in ("scipy:DOP853",) + (("scipy:Radau",) if name == "knee-extension" else ()):
        r = ts.simulate(model, scipy_method, rtol=1e-9, atol=1e-11, tolerance=None)
        assert np.max(np.abs(r.q - reference.q)) < 1e-5


def test_smooth_chain_case_is_smooth():
    """The case the orders are measured on has no kink, clamp or slack SE along its path."""
    model, y0 = smooth_chain_case()
    r = ts.simulate(model, "reference", rtol=1e-11, atol=1e-13, initial_state=y0)
    c = r.columns()
    for unit in model.units:
        w = c[f"omega_cc_{unit.name}"]
        assert np.all(unit.direction * w > 0.01)  # flexors shorten, extensors lengthen
        assert np.all(np.abs(w) < unit.parameters.max_velocity)
        assert np.all(c[f"torque_{unit.name}"] > 1.0)
    assert np.ptp(r.q, axis=0).min() > math.radians(5)


_FROZEN = np.load(__import__("pathlib").Path(__file__).parent / "data"
                  / "elbow_v0_1_trajectories.npz")
_FROZEN_RUNS = {
    "monolithic_0.1ms": dict(method="monolithic", step=1e-4),
    "monolithic_0.25ms": dict(method="monolithic", step=2.5e-4),
    "partitioned_0.1ms": dict(method="partitioned", step=1e-4),
    "partitioned_body-first_0.1ms": dict(method="partitioned", step=1e-4,
                                         coupling=ts.Coupling(order="body-first")),
    "partitioned_muscles-first_0.1ms": dict(method="partitioned", step=1e-4,
                                            coupling=ts.Coupling(order="muscles-first")),
    "partitioned_linear_0.1ms": dict(method="partitioned", step=1e-4,
                                     coupling=ts.Coupling(predictor="linear")),
    "partitioned_m4_0.1ms": dict(method="partitioned", step=1e-4,
                                 coupling=ts.Coupling(muscle_substeps=4)),
    "partitioned_iter3_0.1ms": dict(method="partitioned", step=1e-4,
                                    coupling=ts.Coupling(iterations=3, tolerance=1e-12)),
    "partitioned_every-stage_0.1ms": dict(method="partitioned", step=1e-4,
                                          coupling=ts.Coupling(order="every-stage")),
    "imex_1ms": dict(method="imex", step=1e-3),
    "imex_5ms": dict(method="imex", step=5e-3),
    "partitioned_sdirk2_m2_1ms": dict(method="partitioned", step=1e-3, coupling=ts.Coupling(
        muscle_solver="sdirk2", muscle_substeps=2)),
}


@pytest.mark.parametrize("name", list(_FROZEN_RUNS))
def test_elbow_preset_reproduces_the_single_elbow_code(name):
    """Every method on builtin:elbow-curl against the trajectories of torquesim 0.1 (the
    elbow-only code, tests/data): the same to 1e-12 rad, with the same work counts."""
    run = ts.simulate(ts.load_model("builtin:elbow-curl"), check=False, **_FROZEN_RUNS[name])
    k = max(1, int(round(1e-2 / (run.time[1] - run.time[0]))))
    assert np.max(np.abs(run.states[::k] - _FROZEN[f"{name}/states"])) <= 1e-12
    # 0.1 counted two implicit unit-equation residuals as one muscle evaluation; they are
    # counted apart now (Newton iterations). And 0.1 evaluated the residual at the eccentric
    # clamp first in every solve, which is now evaluated only where the iteration needs it:
    # one residual evaluation per implicit solve fewer (no clamp is reached on these runs)
    old_muscle = run.cost.rhs_muscle + math.ceil(
        (run.cost.newton_iterations + run.cost.implicit_solves) / 2)
    if _FROZEN_RUNS[name].get("coupling") == ts.Coupling(order="every-stage"):
        # it runs the monolithic loop now: 0.1's partitioned loop evaluated the muscles once
        # more per step, at its start, for nothing but its stability guard
        old_muscle += run.cost.steps
    assert [run.cost.steps, run.cost.rhs_body, old_muscle] == _FROZEN[f"{name}/cost"].tolist()


@pytest.fixture(scope="module")
def fine_fixed_step_curl():
    """The default curl by monolithic RK4 at 25 µs: within 4e-9 rad of itself at 50 µs."""
    return ts.simulate(ts.load_model("builtin:elbow-curl"), "monolithic", 2.5e-5, check=False)


@pytest.mark.parametrize("run, bound", [
    (dict(method="scipy:DOP853", rtol=1e-8, atol=1e-11, tolerance=None), 1e-5),
    (dict(method="reference"), 1e-7),
])
def test_adaptive_runs_meet_their_tolerance_against_a_fine_fixed_step_run(
        fine_fixed_step_curl, run, bound):
    """SciPy's adaptive runs promise an accuracy, not bits: their step sequence moves with the
    library release and the CPU (DOP853 at rtol 1e-8 moved 3.7e-8 rad here and 1.05e-6 rad on
    another machine from the 0.1 golden). So they are held to 1000·rtol of the angle and speed
    of a fine fixed-step run (the model's kinks make the global error a few times the local
    tolerance: measured 4e-8 and 4e-10 rad on SciPy 1.17); only our own fixed-step runs are
    frozen bit for bit (above)."""
    adaptive = ts.simulate(ts.load_model("builtin:elbow-curl"), check=False, **run)
    fine = fine_fixed_step_curl
    k = int(round((adaptive.time[1] - adaptive.time[0]) / (fine.time[1] - fine.time[0])))
    assert np.allclose(adaptive.time, fine.time[::k], atol=1e-12, rtol=0)
    error = np.abs(adaptive.states - fine.states[::k]).max(axis=0)
    assert error[0] <= bound and error[1] <= 10 * bound, error[:2]


def test_equilibrium_shares_the_load_between_two_agonists():
    """Two "equilibrium" flexors on one joint hold it at one common activation."""
    base = ts.load_model("builtin:elbow-curl")
    flexor = base.units[0]
    twin = replace(flexor, name="elbow_flexor_2")
    model = base.replace(units=(*base.units, twin))
    start = model.initial_state()
    assert start.levels[0] == pytest.approx(start.levels[2], abs=1e-12)
    assert start.levels[0] < base.initial_state().levels[0]
    rates = chain_derivative(0.0, start.state, *model.pack())
    assert np.max(np.abs(rates[1:])) < 1e-9


def test_a_start_no_unit_can_hold_names_the_joint():
    knee = ts.load_model("builtin:knee-extension")
    heavy = knee.replace_segment("shank_foot", loads=(ts.PointLoad("weight", 150.0, 0.4),))
    with pytest.raises(ts.ModelError) as info:
        heavy.replace_joint("knee", initial_angle=math.radians(20.0))
    assert info.value.field == "joints.knee.initial_angle" and "> 1" in str(info.value)


BAD_CHAINS = [
    ("segments = []\njoints = []\nunits = []\n", "segments"),
    ("name = 'x'\n", "segments"),
    ("[[segments]]\nname = 's'\nmass = -1.0\ncom_distance = 0.1\ninertia_about_joint = 0.1\n"
     "[[joints]]\nname = 'j'\ninitial_angle = 0.1\n", "segments[0].mass"),
    ("units = []\n[[segments]]\nname = 's'\nmass = 1.0\ncom_distance = 0.1\n"
     "inertia_about_joint = 0.1\n[[segments]]\nname = 's'\nmass = 1.0\ncom_distance = 0.1\n"
     "inertia_about_joint = 0.1\n"
     "[[joints]]\nname = 'j'\ninitial_angle = 0.1\n[[joints]]\nname = 'k'\n"
     "initial_angle = 0.1\n", "segments[1].name"),
    ("[[segments]]\nname = 's'\nmass = 1.0\ncom_distance = 0.1\ninertia_about_joint = 0.1\n",
     "joints"),
]


def _unit_toml(name: str, joint: str, direction: str = "flexor") -> str:
    fields = ts.TorqueGeneratorUnit.flexor_default().as_dict()
    body = "\n".join(f"{k} = {v!r}" for k, v in fields.items())
    return (f"[[units]]\nname = '{name}'\njoint = '{joint}'\ndirection = '{direction}'\n"
            f"{body}\n[units.activation]\ninitial_level = 'equilibrium'\n")


_ONE = ("[[segments]]\nname = 's'\nmass = 1.0\ncom_distance = 0.1\n"
        "inertia_about_joint = 0.1\n[[joints]]\nname = 'elbow'\ninitial_angle = 0.2\n")


@pytest.mark.parametrize("text, field", [
    *BAD_CHAINS,
    ("units = []\n" + _ONE, "joints.elbow"),  # a joint with no unit
    (_ONE, "units"),  # no units at all
    (_ONE + _unit_toml("f", "knee"), "units[0].joint"),  # a unit on an unknown joint
    (_ONE + _unit_toml("f", "elbow", "sideways"), "units[0].direction"),
    (_ONE + _unit_toml("f", "elbow").replace("se_stiffness = 600.0\n", ""),
     "units[0].se_stiffness"),
    (_ONE + _unit_toml("f", "elbow").replace("joint = 'elbow'", "joint = 'elbow'\ncolour = 1"),
     "units[0].colour"),
    (_ONE + _unit_toml("f", "elbow") + _unit_toml("f", "elbow"), "units[1].name"),
    ("units = []\n" + "".join(f"[[segments]]\nname = 's{k}'\nmass = 1.0\ncom_distance = 0.1\n"
                              f"inertia_about_joint = 0.1\nlength = 0.2\n" for k in range(17))
     + "".join(f"[[joints]]\nname = 'j{k}'\ninitial_angle = 0.1\n" for k in range(17)),
     "segments"),
    (_ONE.replace("mass = 1.0\n", "mass = 1.0\nloads = [{name = 'w', mass = -2.0, "
                  "distance = 0.1}]\n") + _unit_toml("f", "elbow"), "segments[0].loads[0].mass"),
    (_ONE.replace("inertia_about_joint = 0.1", "inertia_about_joint = 0.001")
     + _unit_toml("f", "elbow"), "segments[0].inertia_about_joint"),
])
def test_bad_chain_files_name_the_field(tmp_path, text, field):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ts.ModelError) as info:
        ts.load_model(path)
    assert info.value.field == field, str(info.value)
    assert "\n" not in str(info.value)


def test_bad_chain_file_on_the_command_line_is_one_line_exit_2(tmp_path, capsys):
    from torquesim.cli import main

    path = tmp_path / "bad.toml"
    path.write_text(_ONE + _unit_toml("f", "knee"))
    code = main(["simulate", "--model", str(path), "--out", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error: units[0].joint") and err.count("\n") == 1
    assert not (tmp_path / "o.csv").exists()


def test_python_api_type_errors_name_the_argument():
    with pytest.raises(TypeError, match="model"):
        ts.simulate("builtin:elbow-curl")
    with pytest.raises(TypeError, match="coupling"):
        ts.simulate(None, "partitioned", 1e-3, coupling="linear")
    assert ts.simulate(None, "imex", np.float64(5e-3), duration=np.float32(0.5)).success
