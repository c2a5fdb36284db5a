"""Free bodies against the ground: the free-base tree equations against an independent Kane
model, the laws of motion a jump must obey (flight under −g, angular momentum about the
centre of mass, impulse and momentum, standing on body weight), the energy balance of a
passive body dropped onto the ground, the squat-jump preset, and the bad inputs."""

import math
import tomllib
from dataclasses import replace

import numpy as np
import pytest

import torquesim as ts
from torquesim.io.model_file import model_from_dict, model_to_toml
from torquesim.model.body import body_work_size, joint_accelerations
from torquesim.model.contact import GroundContact, Point
from torquesim.solvers.rates import chain_derivative

G = 9.81


def _pair(joint: str) -> tuple[ts.Unit, ts.Unit]:
    strong = replace(ts.TorqueGeneratorUnit.flexor_default(), isometric_torque=500.0,
                     eccentric_torque_max=700.0, se_stiffness=5000.0)
    return tuple(ts.Unit(f"{joint}_{side}", joint, d, strong, ts.ActivationProfile(None))
                 for side, d in (("f", 1), ("e", -1)))


def tree_model(**changes) -> ts.ChainModel:
    """A free tree: a trunk (the root, its proximal point at the hips, pointing up), two legs
    on it, a shin on the first leg; a contact at the shin's end and at the second leg's."""
    segments = (
        ts.Segment("trunk", 30.0, 0.3, 30.0 * 0.3**2 + 1.2, 0.6),
        ts.Segment("leg1", 8.0, 0.2, 8.0 * 0.2**2 + 0.1, 0.42, parent="trunk",
                   parent_distance=0.0),
        ts.Segment("leg2", 9.0, 0.22, 9.0 * 0.22**2 + 0.12, 0.45, parent="trunk",
                   parent_distance=-0.05),
        ts.Segment("shin", 4.0, 0.18, 4.0 * 0.18**2 + 0.05, 0.4, parent="leg1",
                   loads=(ts.PointLoad("shoe", 1.0, 0.38, 0.002),)),
    )
    joints = (ts.Joint("free", initial_angle=math.pi, endstop_torque=0.0,
                       endstop_lower_angle=-math.pi, endstop_upper_angle=2 * math.pi),
              ts.Joint("hip1", initial_angle=3.08, endstop_torque=0.0,
                       endstop_lower_angle=-3.0, endstop_upper_angle=3.5),
              ts.Joint("hip2", initial_angle=-3.08, endstop_torque=0.0,
                       endstop_lower_angle=-3.1, endstop_upper_angle=3.0),
              ts.Joint("knee1", initial_angle=0.05, endstop_torque=0.0,
                       endstop_lower_angle=-1.0, endstop_upper_angle=2.5))
    units = (*_pair("hip1"), *_pair("hip2"), *_pair("knee1"))
    points = (Point("foot", "shin", 0.4, -0.1), Point("toe", "leg2", 0.45, 0.08))
    model = ts.ChainModel("tree", segments, joints, units, duration=0.3, base="free",
                          points=points, contacts=(GroundContact("foot"),
                                                   GroundContact("toe", damping=2.0)))
    return model.replace(**changes) if changes else model


def contact_law(height, vy, vx, contact: GroundContact) -> tuple[float, float]:
    """Hunt–Crossley and regularised Coulomb, written here from their definitions."""
    if height >= 0:
        return 0.0, 0.0
    normal = contact.stiffness * (-height) ** contact.exponent * (1 - contact.damping * vy)
    normal = max(normal, 0.0)
    return -contact.friction * normal * vx / math.hypot(vx, contact.slip_speed), normal


def sympy_tree(model):
    """The model's free tree built independently with sympy.physics.mechanics (Kane): a
    base point moving in x and y, frames rotated by the joint angles about z, rigid bodies and
    particles at their points, gravity on every mass, each joint torque on its segment and,
    reversed, on the parent, and given contact forces at the contact points. Returns
    (accelerations(q, u, torques, forces), point kinematics(q, u))."""
    import sympy as sp
    import sympy.physics.mechanics as me

    n, nb = model.n_coordinates, model.n_base
    q = me.dynamicsymbols(f"q0:{n}")
    u = me.dynamicsymbols(f"u0:{n}")
    tau = sp.symbols(f"tau0:{n}")
    forces = sp.symbols(f"F0:{2 * len(model.contacts)}")
    ground = me.ReferenceFrame("N")
    origin = me.Point("O")
    origin.set_vel(ground, 0)
    if nb:
        base = origin.locatenew("B", q[0] * ground.x + q[1] * ground.y)
        base.set_vel(ground, u[0] * ground.x + u[1] * ground.y)
    else:
        base = origin
    frames, proximal, bodies, loads = [], [], [], []
    for k, seg in enumerate(model.segments):
        parent = model.parents[k]
        reference = ground if parent < 0 else frames[parent]
        angle = q[nb + k] + (model.base_angle if parent < 0 else 0)
        frame = reference.orientnew(f"A{k}", "Axis", [angle, ground.z])
        path, p = [k], parent
        while p >= 0:
            path.append(p)
            p = model.parents[p]
        frame.set_ang_vel(ground, sum(u[nb + j] for j in path) * ground.z)
        if parent < 0:
            joint = base
        else:
            joint = proximal[parent].locatenew(f"J{k}", model.parent_distances()[k]
                                               * -frames[parent].y)
            joint.v2pt_theory(proximal[parent], ground, frames[parent])
        frames.append(frame)
        proximal.append(joint)
        pieces = [(seg.mass, seg.com_distance, seg.inertia_about_joint
                   - seg.mass * seg.com_distance**2, f"c{k}")]
        pieces += [(ld.mass, ld.distance, ld.inertia, f"l{k}{ld.name}") for ld in seg.loads]
        for mass, r, own, name in pieces:
            point = joint.locatenew(name, r * -frame.y)
            point.v2pt_theory(joint, ground, frame)
            bodies.append(me.RigidBody(name, point, frame, mass,
                                       (me.inertia(frame, 0, 0, own), point)))
            loads.append((point, -mass * model.gravity * ground.y))
        loads.append((frame, tau[nb + k] * ground.z))
        if parent >= 0:
            loads.append((reference, -tau[nb + k] * ground.z))
    names = [s.name for s in model.segments]
    spots = []
    for c, contact in enumerate(model.contacts):
        pt = next(p for p in model.points if p.name == contact.point)
        k = names.index(pt.segment)
        spot = proximal[k].locatenew(f"P{c}", pt.distance * -frames[k].y
                                     + pt.offset * frames[k].x)
        spot.v2pt_theory(proximal[k], ground, frames[k])
        spots.append(spot)
        loads.append((spot, forces[2 * c] * ground.x + forces[2 * c + 1] * ground.y))
    kane = me.KanesMethod(ground, q_ind=q, u_ind=u,
                          kd_eqs=[q[i].diff() - u[i] for i in range(n)])
    kane.kanes_equations(bodies, loads)
    mass = sp.lambdify([q, u, tau, forces], kane.mass_matrix, "numpy")
    forcing = sp.lambdify([q, u, tau, forces], kane.forcing, "numpy")
    where = sp.lambdify([q, u], [[s.pos_from(origin).dot(ground.x),
                                  s.pos_from(origin).dot(ground.y),
                                  s.vel(ground).dot(ground.x), s.vel(ground).dot(ground.y)]
                                 for s in spots], "numpy")

    def accelerations(qv, uv, torques, f):
        return np.linalg.solve(mass(qv, uv, torques, f), forcing(qv, uv, torques, f)).ravel()

    return accelerations, where


@pytest.mark.slow
def test_free_tree_equations_agree_with_kane():
    model = tree_model()
    accelerations, where = sympy_tree(model)
    seg, joints = model.segment_array(), model.joint_array().ravel()
    n = model.n_coordinates
    work = np.empty(body_work_size(n, seg))
    rng = np.random.default_rng(3)
    start = model.initial_state().state[:n]
    loaded = 0
    for _ in range(12):
        q = start + rng.normal(0, [0.05, 0.001, 0.01, 0.01, 0.01, 0.01]) - [0, 0.002, 0, 0, 0, 0]
        u = rng.normal(0, 1.5, n)
        torques = np.concatenate([[0, 0, 0], rng.normal(0, 20, n - 3)])
        forces = np.concatenate([contact_law(py, vy, vx, c)
                                 for (px, py, vx, vy), c in zip(where(q, u), model.contacts,
                                                                strict=True)])
        loaded += np.count_nonzero(forces[1::2])
        joint_accelerations(np.concatenate([q, u]), n, torques, seg, joints, work)
        expected = accelerations(q, u, torques, forces)
        np.testing.assert_allclose(work[n * n: n * n + n], expected, rtol=1e-9,
                                   atol=1e-9 * np.abs(expected).max())
    assert loaded >= 6  # the contacts really pushed in most states


@pytest.mark.slow
def test_fixed_tree_equations_agree_with_kane():
    """Two arms on a trunk that hangs from a fixed pivot (a tree on a fixed base): the same
    solve against the same independent Kane model, without the base coordinates."""
    segments = (ts.Segment("trunk", 20.0, 0.25, 20.0 * 0.25**2 + 0.8, 0.5),
                ts.Segment("arm1", 3.0, 0.15, 3.0 * 0.15**2 + 0.02, 0.3, parent="trunk",
                           parent_distance=0.45),
                ts.Segment("arm2", 2.5, 0.14, 2.5 * 0.14**2 + 0.02, 0.28, parent="trunk",
                           parent_distance=0.4),
                ts.Segment("hand", 0.5, 0.05, 0.5 * 0.05**2 + 0.001, 0.1, parent="arm1"))
    joints = tuple(ts.Joint(name, initial_angle=0.0, endstop_torque=0.0)
                   for name in ("pivot", "shoulder1", "shoulder2", "wrist"))
    units = tuple(u for j in joints for u in _pair(j.name))
    model = ts.ChainModel("fixed_tree", segments, joints, units, base_angle=0.2)
    assert not model.is_serial
    accelerations, _ = sympy_tree(model)
    seg, packed_joints = model.segment_array(), model.joint_array().ravel()
    n = model.n_coordinates
    work = np.empty(body_work_size(n, seg))
    rng = np.random.default_rng(5)
    for _ in range(8):
        q, u, torques = rng.normal(0, 1.0, n), rng.normal(0, 2.0, n), rng.normal(0, 30, n)
        joint_accelerations(np.concatenate([q, u]), n, torques, seg, packed_joints, work)
        expected = accelerations(q, u, torques, [])
        np.testing.assert_allclose(work[n * n: n * n + n], expected, rtol=1e-9,
                                   atol=1e-9 * np.abs(expected).max())
    short = model.replace(duration=0.2)  # the loops run trees (at a step within the limit)
    run = ts.simulate(short, "monolithic", 1e-5)
    assert not run.stability.exceeded
    reference = ts.simulate(short, "reference", rtol=1e-11, atol=1e-13)
    assert np.max(np.abs(run.q[::100] - reference.q)) < 1e-6


@pytest.fixture(scope="module")
def jump():
    """The squat-jump preset at a small step, every state kept."""
    model = ts.load_model("builtin:squat-jump")
    return ts.simulate(model, "monolithic", 1.25e-5)


def test_standing_still_rests_on_body_weight():
    """The static start on the ground: the contacts carry the weight with no net moment,
    nothing accelerates, and with the activations held the body stays put (standing is an
    inverted pendulum: unstable without feedback, so only for 50 ms, within 1e-6)."""
    model = ts.load_model("builtin:squat-jump")
    still = model.replace(units=tuple(
        u.__class__(u.name, u.joint, u.direction, u.parameters,
                    ts.ActivationProfile(u.activation.initial_level))
        for u in model.units), duration=0.05)
    start = still.initial_state()
    rates = chain_derivative(0.0, start.state, *still.pack())
    assert np.max(np.abs(rates)) < 1e-9
    run = ts.simulate(still, "monolithic", 2.5e-5)
    assert not run.stability.exceeded
    c = run.columns()
    weight = G * sum(s.total_mass for s in model.segments)
    assert abs(c["grf_y"][0] - weight) < 1e-9 * weight
    assert np.max(np.abs(c["grf_y"] - weight)) < 1e-6 * weight
    assert np.max(np.abs(run.states - run.states[0])) < 1e-6
    assert np.max(np.abs(c["grf_x"])) < 1e-6


def test_flight_follows_gravity_and_keeps_angular_momentum(jump):
    c = jump.columns()
    air = np.flatnonzero(c["grf_y"] == 0.0)
    assert air.size > 1000  # 25 µs steps: over 25 ms of flight
    h = jump.step
    flight = slice(air[0] + 1, air[-1])
    accel = np.diff(c["com_speed_y"])[flight] / h
    assert np.max(np.abs(accel + G)) < 1e-7
    assert np.max(np.abs(np.diff(c["com_speed_x"])[flight])) / h < 1e-7
    momentum = angular_momentum(jump)[air[0]: air[-1]]
    assert np.ptp(momentum) < 1e-9 * max(1.0, np.abs(momentum).max())
    assert np.abs(momentum).max() > 0.1  # the body does turn in flight


def angular_momentum(run) -> np.ndarray:
    """Σ m·(r − r_com) × v + I_own·φ̇ about the centre of mass, kg·m²/s, from the segments'
    own centres (loads are on the segment axes and the presets have none)."""
    model = run.model
    layout = model.layout
    q, qd = run.states[:, layout.coordinates], run.states[:, layout.coordinate_speeds]
    where = model.kinematics(q, qd)
    velocity = where["centre_velocities"]
    com_v = where["com_velocity"][:, None, :]
    arm = where["centres"] - where["com"][:, None, :]
    rel = velocity - com_v
    total = 0.0
    phid = np.cumsum(qd[:, model.n_base:], axis=1)  # a serial chain's absolute rates
    for k, seg in enumerate(model.segments):
        own = seg.inertia_with_loads - seg.first_moment**2 / seg.total_mass
        total = total + seg.total_mass * (arm[:, k, 0] * rel[:, k, 1]
                                          - arm[:, k, 1] * rel[:, k, 0]) + own * phid[:, k]
    return total


def test_impulse_equals_change_of_momentum(jump):
    c = jump.columns()
    mass = sum(s.total_mass for s in jump.model.segments)
    h = jump.step
    for force, speed, weight in (("grf_y", "com_speed_y", mass * G), ("grf_x", "com_speed_x", 0)):
        net = c[force] - weight
        impulse = np.concatenate([[0.0], np.cumsum(0.5 * (net[1:] + net[:-1]) * h)])
        change = mass * (c[speed] - c[speed][0])
        scale = np.abs(change).max() if force == "grf_y" else mass * 1.0
        assert np.max(np.abs(impulse - change)) < 1e-6 * scale, force


def test_the_squat_jump_is_a_jump(jump):
    """Issue 31's person: a flight v²/2g of 0.25-0.35 m (recorded squat jumps of active
    adults), take-off nearly vertical (|v_x| ≤ 0.15 m/s), no end stop above 5 % of its
    joint's peak muscle torque at any time, the apex where the take-off speed says."""
    c = jump.columns()
    take_off = np.argmax(c["grf_y"] == 0.0)
    assert 0.2 < jump.time[take_off] < 0.4
    weight = G * sum(s.total_mass for s in jump.model.segments)
    assert 1.5 < c["grf_y"].max() / weight < 3.5
    vy = c["com_speed_y"][take_off]
    assert 0.25 < vy**2 / (2 * G) < 0.35
    assert abs(c["com_speed_x"][take_off]) <= 0.15
    for joint in jump.model.joints[1:]:
        passive = np.abs(c[f"torque_passive_{joint.name}"]).max()
        assert passive <= 0.05 * np.abs(c[f"torque_net_{joint.name}"]).max(), joint.name
    apex_from_take_off = c["com_y"][take_off] + vy**2 / (2 * G)
    assert abs(apex_from_take_off - c["com_y"].max()) < 1e-5


def test_the_countermovement_jump_starts_from_quiet_standing_and_jumps():
    """Issue 31's countermovement jump: at rest standing upright (the ground carries the
    weight, every speed zero) until its first ramp (53 ms); a countermovement (the ground
    force below body weight while the centre of mass falls more than 0.2 m, then above it); a
    take-off nearly vertical (|v_x| ≤ 0.15 m/s) with a flight of 0.15-0.35 m; no end stop
    above 5 % of its joint's peak muscle torque; the apex where the take-off speed says."""
    model = ts.load_model("builtin:countermovement-jump")
    assert model.duration > 0.9
    run = ts.simulate(model, "imex", 2.5e-4, check=False)
    c = run.columns()
    weight = G * sum(s.total_mass for s in model.segments)
    still = run.time <= 0.053
    assert np.allclose(c["grf_y"][still], weight, rtol=1e-6)
    speeds = run.states[still, model.n_coordinates:2 * model.n_coordinates]
    assert np.abs(speeds).max() < 1e-6
    assert abs(math.degrees(c["knee_angle"][0]) - 4.98) < 0.01  # knee and hip nearly straight
    take_off = int(np.argmax(c["grf_y"] == 0.0))
    assert 0.6 < run.time[take_off] < 1.0
    low = int(np.argmin(c["com_y"][:take_off]))
    assert c["com_y"][0] - c["com_y"][low] > 0.2
    assert c["grf_y"][:low].min() < 0.6 * weight < 2 * weight < c["grf_y"][low:take_off].max()
    vy = c["com_speed_y"][take_off]
    assert 0.15 < vy**2 / (2 * G) < 0.35
    assert abs(c["com_speed_x"][take_off]) <= 0.15
    for joint in model.joints[1:]:
        passive = np.abs(c[f"torque_passive_{joint.name}"]).max()
        assert passive <= 0.05 * np.abs(c[f"torque_net_{joint.name}"]).max(), joint.name
    apex_from_take_off = c["com_y"][take_off] + vy**2 / (2 * G)
    assert abs(apex_from_take_off - c["com_y"].max()) < 1e-4


def dropped_bar():
    """A rigid bar (one free segment, no units) dropped at an angle onto two contacts, 20 cm
    above its resting height, tilted and moving sideways; monolithic RK4 at 10 µs. Returns
    (the run, its contacts)."""
    bar = ts.Segment("bar", 5.0, 0.5, 5.0 * (0.5**2 + 1.0 / 12.0), 1.0)
    contacts = (GroundContact("a", damping=0.5, friction=0.4),
                GroundContact("b", damping=0.5, friction=0.4))
    model = ts.ChainModel("bar", (bar,), (ts.Joint("free", initial_angle=1.7,
                                                   endstop_torque=0.0,
                                                   endstop_lower_angle=-math.pi,
                                                   endstop_upper_angle=2 * math.pi),),
                          (), duration=0.4, base="free",
                          points=(Point("a", "bar", 0.0), Point("b", "bar", 1.0)),
                          contacts=contacts)
    y0 = model.initial_state().state
    y0[1] += 0.2  # 20 cm above its resting height
    y0[2] = 1.9  # tilted
    y0[3] = 0.5  # moving sideways
    return ts.simulate(model, "monolithic", 1e-5, initial_state=y0), contacts


def dropped_bar_energy(run, contacts) -> tuple[np.ndarray, np.ndarray]:
    """The bar's energy (kinetic, gravity, the contacts' springs ∫k·δ^n dδ), J, and the
    energy the contacts' damping and friction dissipated since the start, J, over the run:
    computed from the kinematics and the contact forces, not from the solver's equations."""
    model = run.model
    c = run.columns()
    where = model.kinematics(run.states[:, :3], run.states[:, 3:6])
    energy = 0.5 * 5.0 * np.sum(where["com_velocity"] ** 2, axis=1) \
        + 0.5 * 5.0 / 12.0 * run.states[:, 5] ** 2 + 5.0 * G * where["com"][:, 1]
    dissipated = np.zeros(run.time.size)
    for i, contact in enumerate(contacts):
        y, vx, vy = where["points"][:, i, 1], where["point_velocities"][:, i, 0], \
            where["point_velocities"][:, i, 1]
        depth = np.maximum(-y, 0.0)
        energy += contact.stiffness * depth ** (contact.exponent + 1) / (contact.exponent + 1)
        power = (c[f"grf_y_{contact.point}"] - contact.stiffness * depth**contact.exponent) \
            * (-vy) - c[f"grf_x_{contact.point}"] * vx
        dissipated += np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1])
                                                       * np.diff(run.time))])
    return energy, dissipated


def test_a_passive_body_dropped_loses_energy_only_in_the_contacts():
    """A rigid bar (`dropped_bar`): kinetic + potential + contact spring energy falls exactly
    by what the contacts' damping and friction dissipate."""
    run, contacts = dropped_bar()
    energy, dissipated = dropped_bar_energy(run, contacts)
    assert np.max(run.columns()["grf_y"]) > 5.0 * G  # it did hit the ground
    assert dissipated[-1] > 0.1
    assert np.max(np.abs(energy + dissipated - energy[0])) < 1e-4 * energy[0]


@pytest.mark.parametrize("name", ["squat-jump", "drop-landing"])
def test_ground_model_file_round_trip(name):
    model = ts.load_model(f"builtin:{name}")
    text = model_to_toml(model)
    assert model_from_dict(tomllib.loads(text)) == model
    assert ("landing_speed" in text) == bool(model.landing_speed)


def test_the_drop_landing_starts_at_touchdown_and_absorbs_the_fall():
    """The drop landing (`landing_speed`): at t = 0 the standing posture and unit states,
    lifted so that the lowest contact point is at the ground with no force yet, every point
    moving down at 2.43 m/s; then an impact of several body weights, the knee flexing to
    30-70°, no bounce, no end stop above 5 % of its joint's peak muscle torque, the body
    nearly still at the end. The start is checked against the standing model's own state."""
    model = ts.load_model("builtin:drop-landing")
    start = model.initial_state().state
    standing = model.replace(landing_speed=0.0).initial_state().state
    layout = model.layout
    assert model.landing_speed == pytest.approx(math.sqrt(2 * G * 0.3), abs=0.01)
    lift = start - standing
    assert lift[1] > 0.0
    lift[1] = 0.0
    lift[layout.coordinate_speeds.start + 1] += model.landing_speed
    assert np.max(np.abs(lift)) == 0.0  # only the height and the vertical speed differ
    where = model.kinematics(start[layout.coordinates], start[layout.coordinate_speeds])
    contact_y = where["points"][[p.name for p in model.points].index("toe"), 1], \
        where["points"][[p.name for p in model.points].index("heel"), 1]
    assert min(contact_y) == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(where["point_velocities"][:, 1], -model.landing_speed,
                               rtol=1e-12)
    run = ts.simulate(model, "imex-ros2", 2.5e-4, tolerance=None)
    c = run.columns()
    assert c["grf_y"][0] == 0.0 and np.all(c["grf_y"][1:] > 0.0)  # lands, never leaves
    assert c["grf_y"].max() > 5.0 * model.weight
    assert 30.0 < math.degrees(c["knee_angle"].max()) < 70.0
    for joint in model.joints[1:]:
        passive = np.abs(c[f"torque_passive_{joint.name}"]).max()
        assert passive <= 0.05 * np.abs(c[f"torque_net_{joint.name}"]).max(), joint.name
    assert abs(c["com_speed_y"][-1]) < 0.3 and abs(c["com_speed_x"][-1]) < 0.3
    events = run.ground_events()
    assert events.landing == 0.0 and events.take_off is None
    assert events.sink == pytest.approx(c["com_y"][0] - c["com_y"].min())
    assert any(line.startswith("touchdown") for line in events.summary_lines())


@pytest.mark.parametrize("change, match", [
    (dict(landing_speed=-1.0), r"landing_speed.*\[0, 10\] m/s"),
    (dict(landing_speed=20.0), r"landing_speed.*\[0, 10\] m/s"),
])
def test_bad_landing_speeds_name_the_field(change, match):
    with pytest.raises(ts.ModelError, match=match):
        ts.load_model("builtin:drop-landing").replace(**change)
    with pytest.raises(ts.ModelError) as info:  # a fixed base has no ground to land on
        ts.load_model("builtin:elbow-curl").replace(landing_speed=1.0)
    assert info.value.field == "landing_speed"


@pytest.mark.parametrize("change, field", [
    ({"points": (Point("toe", "foot", 0.9),)}, "points[0].distance"),
    ({"points": (Point("toe", "shoe", 0.1),)}, "points[0].segment"),
    ({"contacts": (GroundContact("nose"),)}, "contacts[0].point"),
    ({"base": "floating"}, "base"),
    ({"base": "fixed"}, "contacts"),
])
def test_bad_ground_models_name_the_field(change, field):
    model = ts.load_model("builtin:squat-jump")
    with pytest.raises(ts.ModelError) as info:
        model.replace(**change)
    assert info.value.field == field, str(info.value)


def test_bad_contact_parameters_and_postures_name_the_field():
    with pytest.raises(ts.ModelError, match=r"stiffness.*\(0, 1e\+09\]"):
        GroundContact("toe", stiffness=-1.0)
    with pytest.raises(ts.ModelError, match=r"friction.*\[0, 5\]"):
        GroundContact("toe", friction=9.0)
    # a slip speed so small that friction's time constant (m·v_s/(μ·F)) is below a µs: before,
    # 1e-30 m/s ran, flagged step/τ = 7e28 at every step the user could give
    with pytest.raises(ts.ModelError, match=r"slip_speed.*\[0.001, 1\] m/s"):
        GroundContact("toe", slip_speed=1e-30)
    model = ts.load_model("builtin:squat-jump")
    with pytest.raises(ts.ModelError) as info:
        model.replace_joint("hip", initial_angle=-0.3)  # trunk far back: it would fall
    assert info.value.field == "joints.initial_angle"
    assert "centre of mass" in str(info.value)
    unit = model.units[0]
    with pytest.raises(ts.ModelError) as info:
        model.replace(units=(*model.units, unit.__class__("spin", "foot_ground", 1,
                                                          unit.parameters, unit.activation)))
    assert info.value.field == "units[6].joint" and "free base" in str(info.value)


def test_jump_events_and_the_grf_file(jump, tmp_path, capsys):
    events = jump.ground_events()
    c = jump.columns()
    i = int(round(events.take_off / jump.step))
    assert c["grf_y"][i] == 0.0 and c["grf_y"][i - 1] > 0.0
    assert events.landing is None  # the preset ends in the air
    assert events.flight_height == pytest.approx(c["com_speed_y"][i] ** 2 / (2 * G))
    assert events.rise == pytest.approx(c["com_y"].max() - c["com_y"][0])
    from torquesim.cli import main

    path = tmp_path / "grf.mot"
    assert main(["simulate", "--model", "builtin:squat-jump", "--step", "0.0125ms",
                 "--grf", str(path)]) == 0
    out = capsys.readouterr().out
    assert "take-off      t = 0.2633" in out and "body weights" in out
    table = ts.read_table(path)
    np.testing.assert_allclose(table["ground_force_vy"], c["grf_y"], rtol=1e-12)
    np.testing.assert_allclose(table["toe_ground_force_vy"] + table["heel_ground_force_vy"],
                               table["ground_force_vy"], rtol=1e-12)
    assert main(["simulate", "--grf", str(tmp_path / "x.mot")]) == 2  # the elbow: no contacts
    assert "--grf" in capsys.readouterr().err and not (tmp_path / "x.mot").exists()


def test_the_stability_guard_watches_the_contacts_in_every_technique():
    """IMEX makes the muscles implicit, not the contacts: at 2 ms a contact's step/τ passes
    the RK4 limit, and the advice is a smaller step or Radau, not IMEX."""
    model = ts.load_model("builtin:squat-jump")
    run = ts.simulate(model, "imex", 2e-3, tolerance=None, check=False)
    assert run.stability.exceeded and run.stability.in_contact
    assert run.stability.unit in ("ground contact at toe", "ground contact at heel")
    assert "'reference'" in run.message and "'imex'" not in run.message
    fine = ts.simulate(model, "imex", 1e-4, tolerance=None)
    assert not fine.stability.exceeded
    assert fine.stability.max_step_ratio < 2.785 / 2


def test_the_guard_sees_friction_where_it_makes_the_run_wrong():
    """With a stiff friction (v_s = 0.01 m/s) a 50 µs step is within the normal force's limit
    but not the friction's: the horizontal ground force goes wrong (chatters), and the guard
    must say so; at 25 µs it is right and the guard is quiet. The judge is the run itself: its
    force against one at a quarter of the step."""
    model = ts.load_model("builtin:squat-jump")
    model = model.replace(contacts=tuple(replace(c, slip_speed=0.01) for c in model.contacts),
                          duration=0.2)
    truth = ts.simulate(model, "imex", 6.25e-6, tolerance=None, check=False)

    def force_error(step):
        run = ts.simulate(model, "imex", step, tolerance=None, check=False)
        every = int(round(step / 6.25e-6))
        error = run.columns()["grf_x"] - truth.columns()["grf_x"][::every]
        return run, float(np.sqrt(np.mean(error**2)))

    coarse, coarse_error = force_error(5e-5)
    fine, fine_error = force_error(2.5e-5)
    weight = model.gravity * sum(s.total_mass for s in model.segments)
    assert coarse_error > 0.05 * weight and coarse.stability.exceeded
    assert "ground contact" in coarse.stability.unit
    assert fine_error < 1e-3 * weight and not fine.stability.exceeded


def test_bad_ground_model_file_is_one_line_exit_2(tmp_path, capsys):
    from torquesim.cli import main

    text = model_to_toml(ts.load_model("builtin:squat-jump"))
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("stiffness = 5000000.0", "stiffness = -3.0", 1))
    out = tmp_path / "run.csv"
    assert main(["simulate", "--model", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "contacts[0].stiffness" in err and "(0, 1e+09]" in err
    assert not out.exists()
