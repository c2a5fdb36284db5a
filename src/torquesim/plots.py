"""Figures. Plot functions take results and return Matplotlib figures; nothing here computes."""

from __future__ import annotations

import textwrap

import numpy as np


def plot_result(result, *, target=None, channels=None):
    """Per joint (one row each): the joint angle (deg), each unit's torque at the joint with
    its sign (d·T) and the net muscle torque (N·m; both with the joint's `Joint.positive`
    motion +, flexion unless the model says otherwise), and its units' activations. A body
    on the ground is drawn as `plot_jump` draws it. With a ``target``, a fourth panel per
    scored joint shows the residual (simulated − target, deg) with its RMS and maximum.

    ``target`` is an optional (time, angle rad) pair drawn over the first joint's angle, or a
    dict joint name → (time, angle rad). ``channels`` (a body on the ground): a dict
    ``grf_x|grf_y|com_x|com_y`` → (time, target values in N or m), drawn in a last row with
    the simulated ones and their residuals (% of body weight, cm).
    """
    if result.model.contacts and target is None and not channels:
        return plot_jump(result)
    cols = result.columns()
    model = result.model
    t = cols["time"]
    n = model.n_joints
    targets = target if isinstance(target, dict) else (
        {model.joints[0].name: target} if target is not None else {})
    ncols = 4 if targets else 3
    channels = channels or {}
    fig, axes = _figure_grid(n + bool(channels), ncols,
                             (4.4 * ncols, 2.9 * (n + bool(channels)) + 0.8))
    if channels:
        _channel_row(axes[n], cols, channels,
                     model.weight)
    for row, joint in enumerate(model.joints):
        ax_angle = axes[row][0]
        _joint_row(axes[row][:3], model, joint,
                   [(f"simulated ({result.method})", cols, "-", 1.5)])
        if joint.name in targets:
            tt, goal = targets[joint.name]
            ax_angle.plot(tt, np.degrees(goal), ls=(0, (4, 3)), color="tab:red", lw=1.6,
                          label="target", zorder=3)
            residual = np.interp(tt, t, np.degrees(cols[joint.coordinate])) - np.degrees(goal)
            ax_res = axes[row][3]
            rms, worst = float(np.sqrt(np.mean(residual**2))), float(np.max(np.abs(residual)))
            ax_res.plot(tt, residual, color="tab:red")
            ax_res.axhline(0.0, color="grey", lw=0.8)
            ax_res.set_ylabel(f"{joint.name} residual (deg)")
            ax_res.set_title(f"RMS {rms:.3f}°, max {worst:.3f}°", fontsize="medium")
            ax_res.grid(alpha=0.3)
        elif targets:
            axes[row][3].set_axis_off()
        _legends(axes[row][:3], "small")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    title = f"torquesim: {model.name}, {result.method}"
    if result.step:
        title += f", h = {result.step * 1e3:g} ms"
    fig.suptitle(textwrap.fill(title, 80))
    return fig


def _joint_row(axes, model, joint, runs) -> None:
    """One joint's row of a result figure, for each of ``runs`` ((label, `columns()` of a
    result, line style, line width)): the joint angle (deg), the net muscle torque and each
    unit's torque at the joint with its sign (d·T; N·m, the joint's `Joint.positive` motion
    +), and the units' activations. Each unit keeps its colour across runs; the runs differ by
    line style. `plot_result` (one run) and `plot_comparison` (two) draw their rows here."""
    ax_angle, ax_torque, ax_act = axes
    units = [u for u in model.units if u.joint == joint.name]
    for label, cols, style, width in runs:
        tag = f", {label}" if len(runs) > 1 else ""
        t = cols["time"]
        ax_angle.plot(t, np.degrees(cols[joint.coordinate]), color="k", ls=style, lw=width,
                      label=label)
        for i, u in enumerate(units):
            sign = "+" if u.direction == 1 else "−"
            ax_torque.plot(t, u.direction * cols[f"torque_{u.name}"], color=f"C{i}", ls=style,
                           lw=width * 0.8, label=f"{u.name} ({sign}){tag}")
            ax_act.plot(t, cols[f"activation_{u.name}"], color=f"C{i}", ls=style, lw=width,
                        label=f"{u.name}{tag}")
        ax_torque.plot(t, cols[f"torque_net_{joint.name}"], color="k", ls=style,
                       lw=width * 0.7, label=f"net{tag}")
    ax_angle.set_ylabel(f"{joint.coordinate} (deg, {joint.positive} +)")
    ax_torque.axhline(0.0, color="grey", lw=0.6)
    ax_torque.set_ylabel(f"{joint.name} torque, {joint.positive} + (N·m)")
    ax_act.set_ylim(0.0, 1.05)
    ax_act.set_ylabel("activation (0–1)")
    if not units:  # a free base's joint
        ax_act.text(0.5, 0.5, f"no units at {joint.name}", ha="center", va="center",
                    transform=ax_act.transAxes, color="grey")
    for ax in axes:
        ax.grid(alpha=0.3)


def _legends(axes, size: str) -> None:
    """A legend on each of ``axes`` that has labelled lines."""
    for ax in axes:
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=size)


def plot_model(model):
    """The model as a picture: left, the chain at its initial angles (segments from the base,
    joints as circles with their name, initial angle in degrees and `Joint.positive` motion,
    placed outside the joint's bend, centres of mass and point loads with their mass,
    gravity), and which units act where (+ towards the positive motion);
    right, each unit's property curves: tetanic torque T_ω(ω_cc) and CE torque
    d(ω_cc)·T_ω(ω_cc) (N·m, concentric positive), torque/angle factor T_θ(θ_cc), and the SE
    torque against stretch (N·m/rad slope k)."""
    from .model.torque_generator import (
        differential_activation,
        tetanic_torque_velocity,
        torque_angle,
        unit_torque,
    )

    fig = _figure(figsize=(14.0, 6.2))
    grid = fig.add_gridspec(2, 3, width_ratios=(1.6, 1, 1))
    ax = fig.add_subplot(grid[:, 0])
    start_state = model.initial_state().state[:model.n_coordinates]
    pose = model.kinematics(start_state)
    phi = pose["angles"]
    axis = np.column_stack([np.sin(phi), -np.cos(phi)])
    labels: dict[tuple[float, float], list[str]] = {}
    away: dict[tuple[float, float], np.ndarray] = {}
    for k, seg in enumerate(model.segments):
        direction = axis[k]
        start = pose["joints"][k]
        end = start + _drawn_length(seg) * direction
        ax.plot([start[0], end[0]], [start[1], end[1]], color="k", lw=3, solid_capstyle="round")
        com = start + seg.com_distance * direction
        ax.plot(*com, marker="o", ms=7, mfc="white", mec="k")
        side = np.array([-direction[1], direction[0]])  # the segment's left, drawn as seen
        side = side if side[0] >= 0 else -side  # labels of segments to the right
        ax.annotate(f"{seg.name}\n{seg.mass:.3g} kg", com, xytext=tuple(10 * side),
                    textcoords="offset points", fontsize="small", va="center",
                    ha="left" if side[0] > 0.3 else "center")
        for ld in seg.loads:
            where = start + ld.distance * direction
            ax.plot(*where, marker="s", ms=10, color="tab:grey")
            ax.annotate(f"{ld.name} {ld.mass:g} kg", where, xytext=(8, -12),
                        textcoords="offset points", fontsize="small", color="tab:grey")
        joint = model.joints[k]
        units = [u for u in model.units if u.joint == joint.name]
        ax.plot(*start, marker="o", ms=12, color="tab:blue", zorder=4)
        # the label goes away from the segments meeting at the joint (outside its bend)
        parent = model.parents[k]
        meeting = direction - (axis[parent] if parent >= 0 else 0.0)
        across = np.array([-direction[1], direction[0]])
        across = across if across[0] <= 0 else -across  # the root's label to its left
        out = -meeting if parent >= 0 and np.linalg.norm(meeting) > 0.2 else across
        key = (round(float(start[0]), 6), round(float(start[1]), 6))
        away.setdefault(key, out / np.linalg.norm(out))
        labels.setdefault(key, []).append(
            f"{joint.name} {np.degrees(joint.initial_angle):.0f}° ({joint.positive} +)\n"
            + "".join(f"{'+' if u.direction == 1 else '−'} {u.name}\n" for u in units))
    for key, texts in labels.items():
        out = away[key]
        ax.annotate("".join(texts).strip(), key, xytext=tuple(18 * out),
                    textcoords="offset points", fontsize="small", color="tab:blue",
                    ha="left" if out[0] > 0.3 else "right" if out[0] < -0.3 else "center",
                    va="bottom" if out[1] > 0.3 else "top" if out[1] < -0.3 else "center")
    for point, spot in zip(model.points, pose["points"], strict=True):
        ax.plot(*spot, marker="^", ms=8, color="tab:orange")
        ax.annotate(point.name, spot, xytext=(8, -14), textcoords="offset points",
                    fontsize="small", color="tab:orange")
    for poly in outline_polygons(model, pose):
        ax.plot(poly[:, 0], poly[:, 1], color="k", lw=1.2)
    if model.contacts:
        ax.axhline(0.0, color="tab:brown", lw=2)
    ax.annotate("", xy=(0.93, 0.78), xytext=(0.93, 0.95), xycoords="axes fraction",
                arrowprops={"arrowstyle": "->", "color": "grey"})
    ax.text(0.91, 0.86, f"g = {model.gravity:g} m/s²", transform=ax.transAxes, ha="right",
            color="grey", fontsize="small")
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.9, 0.15)
    ax.set_title(textwrap.fill(f"{model.name} at its initial angles; at each joint its angle, "
                               "the motion a growing angle is, and its units (+ pulls that "
                               "way, − the other)"
                               + ("; ▲ points, ground y = 0" if model.contacts else ""), 56),
                 fontsize="medium")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    axes = [fig.add_subplot(grid[r, c]) for r in range(2) for c in (1, 2)]
    a_v, a_d, a_t, a_s = axes
    for unit in model.units:
        p = unit.parameters.to_array()
        w = np.linspace(-unit.parameters.max_velocity, unit.parameters.max_velocity, 401)
        tet = np.array([tetanic_torque_velocity(v, p, 0) for v in w])
        dif = np.array([differential_activation(v, p, 0) for v in w])
        a_v.plot(w, tet, label=unit.name)
        a_d.plot(w, dif * tet, label=unit.name)
        optimum = unit.parameters.optimal_angle
        theta = np.linspace(min(0.0, optimum - 1.5), max(np.pi, optimum + 1.5), 181)
        a_t.plot(np.degrees(theta), [torque_angle(th, p, 0) for th in theta], label=unit.name)
        stretch = np.linspace(-0.02, 0.2, 111)
        a_s.plot(stretch, [unit_torque(s_, p, 0) for s_ in stretch], label=unit.name)
    a_v.set(xlabel="CE velocity ω_cc (rad/s, concentric +)", ylabel="T_ω (N·m)",
            title="tetanic torque/velocity")
    a_d.set(xlabel="CE velocity ω_cc (rad/s, concentric +)", ylabel="d·T_ω (N·m)",
            title="with differential activation")
    a_t.set(xlabel="CE angle θ_cc (deg)", ylabel="T_θ (0–1)", title="torque/angle factor")
    a_s.set(xlabel="SE stretch (rad)", ylabel="unit torque (N·m)", title="series elastic element")
    for a in axes:
        a.grid(alpha=0.3)
        a.title.set_fontsize("medium")
    handles, labels = a_v.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=min(4, len(labels)),
               fontsize="small")
    return fig


def plot_conventions(model, maps: dict | None = None):
    """How the model's angles are measured, drawn on it at its initial pose: for each joint a
    dashed zero line (the parent segment's axis carried on through the joint; for the first
    joint the base's hanging-down direction), an arc from it to the segment with the arrow
    pointing the positive (counterclockwise as drawn) way, and the coordinate's name, value
    in degrees and the motion a growing angle is (`Joint.positive`); the units acting there,
    + pulling towards positive. On a fixed base a
    joint that starts within 23° of its zero is drawn at ±40° (inside its end stops) so that
    its arc can be seen, and the title says so. ``maps``
    ({map name: {joint: expression}}, e.g. the default OpenSim maps) are listed below it."""
    from matplotlib.patches import Arc, FancyArrowPatch

    fig = _figure(figsize=(7.2, 9.0) if maps else (6.4, 5.6))
    grid = fig.add_gridspec(2 if maps else 1, 1, height_ratios=(2.6, 1) if maps else (1,))
    ax = fig.add_subplot(grid[0, 0])
    state = model.initial_state().state[:model.n_coordinates].copy()
    shown = False
    if model.base != "free":
        for k, joint in enumerate(model.joints):
            if abs(state[k]) < 0.4:
                inside = joint.endstop_lower_angle <= 0.7 <= joint.endstop_upper_angle
                state[k] = 0.7 if inside else -0.7
                shown = True
    pose = model.kinematics(state)
    phi = pose["angles"]
    lines = segment_lines(model, state)[0]
    span = float(np.ptp(lines.reshape(-1, 2), axis=0).max()) or 1.0
    radius = 0.11 * span
    colours = ("tab:blue", "tab:red", "tab:green", "tab:purple", "tab:orange", "tab:brown")
    for start, end in lines:
        ax.plot(*np.transpose([start, end]), color="k", lw=3, solid_capstyle="round")
    if model.contacts:
        ax.axhline(0.0, color="tab:brown", lw=2)
    for k, joint in enumerate(model.joints):
        colour = colours[k % len(colours)]
        parent = model.parents[k]
        zero = model.base_angle if parent < 0 else phi[parent]
        centre = pose["joints"][k]
        reach = 1.6 * radius
        ax.plot(*np.transpose([centre, centre + reach * np.array([np.sin(zero),
                                                                     -np.cos(zero)])]),
                ls="--", color=colour, lw=1)
        q = float(state[model.n_base + k])
        # angles on the page: 0 along +x; a direction (sin φ, −cos φ) is at φ − 90°
        a0, a1 = np.degrees(zero) - 90.0, np.degrees(zero + q) - 90.0
        low, high = min(a0, a1), max(a0, a1)
        r = radius * (1.0 + 0.25 * (k % 2))
        ax.add_patch(Arc(centre, 2 * r, 2 * r, theta1=low, theta2=high, color=colour, lw=1.5))
        tip = np.radians(a1)
        before = np.radians(a1 - np.sign(q) * 8.0)
        ax.add_patch(FancyArrowPatch(centre + r * np.array([np.cos(before), np.sin(before)]),
                                     centre + r * np.array([np.cos(tip), np.sin(tip)]),
                                     arrowstyle="-|>", mutation_scale=12, color=colour))
        # the label on the far side of the zero line, away from the segment
        middle = np.radians(a0 - (np.sign(q) or 1.0) * 40.0)
        units = [u for u in model.units if u.joint == joint.name]
        label = f"{joint.coordinate} {np.degrees(q):.0f}°\n({joint.positive} +)" + "".join(
            f"\n{'+' if u.direction == 1 else '−'} {u.name}" for u in units)
        c, s_ = np.cos(middle), np.sin(middle)
        side_on = abs(c) >= 0.5  # label beside the arc, else above or below it
        ax.annotate(label, centre + 1.2 * r * np.array([c, s_]),
                    xytext=(np.sign(c) * 10, 0) if side_on else (0, np.sign(s_) * 8),
                    textcoords="offset points",
                    ha=("left" if c >= 0 else "right") if side_on else "center",
                    va="center" if side_on else ("bottom" if s_ > 0 else "top"),
                    fontsize="small", color=colour, zorder=5,
                    bbox={"fc": "white", "ec": "none", "alpha": 0.85, "pad": 1.0})
    for spot in pose["points"]:
        ax.plot(*spot, marker="^", ms=7, color="tab:orange")
    ends = lines.reshape(-1, 2)
    (x0, y0), (x1, y1) = ends.min(axis=0), ends.max(axis=0)
    # room for the arcs and their labels on every side; equal scales, the box fitted to them
    ax.set_xlim(x0 - 0.7 * span, x1 + 0.6 * span)
    ax.set_ylim(y0 - 0.35 * span, y1 + 0.1 * span)
    ax.set_aspect("equal", adjustable="box")
    ax.set_title(textwrap.fill(f"{model.name}"
                               + (" (drawn at illustrative angles)" if shown else "")
                               + ": each angle from the dashed line to its segment, "
                               "counterclockwise positive as drawn; units + pull that way",
                               60), fontsize="medium")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m), up")
    if maps:
        side = fig.add_subplot(grid[1, 0])
        side.axis("off")
        text = []
        import re

        for name, table in maps.items():
            text.append(f"--map {name} (degrees):")
            for joint, expression in table.items():
                shown = re.sub(r"\d+\.\d{3,}", lambda m: f"{float(m.group()):.2f}", expression)
                text += textwrap.wrap(f"{joint} = {shown}", 80, initial_indent="  ",
                                      subsequent_indent="      ")
            text.append("")
        side.text(0.0, 1.0, "\n".join(text), va="top", ha="left", family="monospace",
                  fontsize="small")
        side.set_title("From an OpenSim model's coordinates", fontsize="medium")
    return fig


def _drawn_length(seg) -> float:
    """A segment is drawn to its next joint, or when it has none over its extent."""
    return seg.length if seg.length > 0 else seg.extent


def segment_lines(model, coordinates) -> np.ndarray:
    """Each segment as a line from its proximal joint to the next joint (the last over its
    extent, `Segment.extent`), m,
    for coordinates (time × `ChainModel.n_coordinates`): shape (time, segments, 2, 2), y up,
    a segment hanging down at zero absolute angle (`ChainModel.kinematics`)."""
    where = model.kinematics(np.atleast_2d(coordinates))
    phi = where["angles"]
    reach = np.array([_drawn_length(seg) for seg in model.segments])
    ends = where["joints"] + reach[None, :, None] * np.stack([np.sin(phi), -np.cos(phi)],
                                                             axis=2)
    return np.stack([where["joints"], ends], axis=2)


#: The ground reaction force as strobe pictures and animations draw it: an arrow at the centre of
#: pressure, this many m per body weight (a 3-body-weight push is 0.75 m, half a body).
FORCE_ARROW_SCALE = 0.25


def joints_with_units(model) -> list:
    """The joints a result figure gives a row: those with units (a free root has none)."""
    return [j for j in model.joints if any(u.joint == j.name for u in model.units)]


def outlines(model) -> list[tuple[int, list[int]]]:
    """Segments drawn as outlines through their points: (segment index, point indices by
    distance along the axis) for each segment with a point off its axis (the jump's foot:
    ankle, heel and toe make its triangle, so the heel is drawn on the foot)."""
    found = []
    for k, seg in enumerate(model.segments):
        mine = [i for i, p in enumerate(model.points) if p.segment == seg.name]
        if any(model.points[i].offset != 0.0 for i in mine):
            found.append((k, sorted(mine, key=lambda i: model.points[i].distance)))
    return found


def outline_polygons(model, where) -> list[np.ndarray]:
    """Closed outlines (`outlines`) at one instant of ``where`` (`ChainModel.kinematics` of a
    single state): each an (n, 2) array, proximal joint first, m."""
    return [np.vstack([where["joints"][k], where["points"][idx], where["joints"][k]])
            for k, idx in outlines(model)]


def _event_lines(axes, events, apex: bool) -> None:
    """Take-off and landing (and the apex, on the centre-of-mass panels) as vertical lines."""
    marks = [(events.take_off, "take-off", "tab:red", "--"),
             (events.landing, "landing", "tab:purple", "--")]
    if apex and events.take_off is not None:
        marks.append((events.apex_time, "apex", "tab:green", ":"))
    for ax in axes:
        for when, label, color, style in marks:
            if when is not None:
                ax.axvline(when, color=color, ls=style, lw=1.0, label=label)


def draw_strobe(ax, result, poses: int = 10) -> None:
    """The run as a stick-figure sequence (strobe), each pose shifted to the right of the one
    before it, light to dark in time, with the time under it, the centre of mass and the
    ground reaction force as an arrow at the centre of pressure (`FORCE_ARROW_SCALE`); the
    poses at take-off and at the apex are among them."""
    model = result.model
    cols = result.columns()
    events = result.ground_events()
    end = float(result.time[-1])
    times = list(np.linspace(0.0, end, poses))
    marked = {}
    if events is not None and events.take_off is not None:
        marked = {events.take_off: "take-off", events.apex_time: "apex"}
        if events.landing is not None:
            marked[events.landing] = "landing"
        spacing = end / max(poses - 1, 1)
        times = sorted([x for x in times if all(abs(x - m) > 0.4 * spacing for m in marked)]
                       + list(marked))
    picks = [int(np.argmin(np.abs(result.time - x))) for x in times]
    coords = result.states[picks][:, :model.n_coordinates]
    lines = segment_lines(model, coords)
    where = model.kinematics(coords)
    weight = model.weight
    height = float(np.ptp(lines[..., 1])) if lines.size else 1.0
    step = max(0.45 * height, float(np.ptp(lines[..., 0], axis=(1, 2)).max()) + 0.1)
    drift = lines[:, 0, 0, 0]  # each pose's root, so the poses keep their own spacing
    for k, i in enumerate(picks):
        shift = k * step - drift[k] + drift[0]
        shade = 0.3 + 0.7 * k / max(len(picks) - 1, 1)
        color = (0.0, 0.0, 0.0, shade)
        for seg in lines[k]:
            ax.plot(seg[:, 0] + shift, seg[:, 1], color=color, lw=2.2, solid_capstyle="round")
        at = {key: value[k] for key, value in where.items()}
        for poly in outline_polygons(model, at):
            ax.plot(poly[:, 0] + shift, poly[:, 1], color=color, lw=1.2)
        if model.base == "free":
            ax.plot(at["com"][0] + shift, at["com"][1], "o", ms=6, mfc="white",
                    mec="tab:red", mew=1.5)
        if model.contacts and cols["grf_y"][i] > 0.0:
            ax.annotate("", xy=(cols["cop_x"][i] + shift + FORCE_ARROW_SCALE * cols["grf_x"][i]
                                / weight, FORCE_ARROW_SCALE * cols["grf_y"][i] / weight),
                        xytext=(cols["cop_x"][i] + shift, 0.0),
                        arrowprops={"arrowstyle": "-|>", "color": "tab:green", "lw": 1.6})
        label = f"{result.time[i]:.2f} s"
        near = [name for when, name in marked.items() if abs(when - result.time[i]) < 1e-9
                or picks[k] == int(np.argmin(np.abs(result.time - when)))]
        if near:
            label += "\n" + near[0]
        ax.text(drift[0] + k * step + 0.05, -0.06, label, ha="center", va="top",
                fontsize="small")
    if model.contacts:
        ax.axhline(0.0, color="tab:brown", lw=1.5)
        x0 = drift[0] - 0.5 * step
        ax.annotate("", xy=(x0, FORCE_ARROW_SCALE), xytext=(x0, 0.0),
                    arrowprops={"arrowstyle": "-|>", "color": "tab:green", "lw": 1.6})
        ax.text(x0 - 0.05, 0.5 * FORCE_ARROW_SCALE, "ground force:\n1 body weight",
                ha="right", va="center", fontsize="small", color="tab:green")
    ax.set_ylim(-0.3, float(lines[..., 1].max()) + 0.1)
    ax.set_xlim(drift[0] - 1.6 * step, drift[0] + (len(picks) - 0.4) * step)
    ax.set_aspect("equal")
    ax.set_ylabel("y (m)")
    ax.set_xticks([])
    ax.set_title("stick figures in time (light to dark), each drawn to the right of the one "
                 "before; ○ centre of mass", fontsize="medium")


def plot_jump(result, poses: int = 10):
    """A movement on the ground as a jump paper shows it: the strobe (`draw_strobe`); the
    vertical and horizontal ground reaction forces in body weights (the body weight line
    marked), the centre of mass's height (m) and its vertical and forward speeds (m/s), with
    take-off, landing and the apex marked; then a row per joint that has units: its angle,
    the units' and net torques and the activations (`_joint_row`)."""
    cols = result.columns()
    model = result.model
    t = cols["time"]
    events = result.ground_events()
    acting = joints_with_units(model)
    rows = 2 + len(acting)
    fig = _figure(figsize=(13.2, 2.7 * len(acting) + 6.6))
    grid = fig.add_gridspec(rows, 3, height_ratios=(1.2, 1.0, *[1.0] * len(acting)))
    draw_strobe(fig.add_subplot(grid[0, :]), result, poses)
    first = fig.add_subplot(grid[1, 0])
    axes = [[first, fig.add_subplot(grid[1, 1], sharex=first),
             fig.add_subplot(grid[1, 2], sharex=first)]]
    axes += [[fig.add_subplot(grid[r, c], sharex=first) for c in range(3)]
             for r in range(2, rows)]
    ax_grf, ax_com, ax_speed = axes[0]
    weight = model.weight
    ax_grf.plot(t, cols["grf_y"] / weight, color="k", label="vertical")
    ax_grf.plot(t, cols["grf_x"] / weight, color="tab:blue", label="horizontal (forwards +)")
    ax_grf.axhline(1.0, color="grey", ls=":", lw=1.0, label="body weight")
    ax_grf.set_ylabel(f"ground reaction force\n(body weights, 1 = {weight:.0f} N)")
    ax_com.plot(t, cols["com_y"], color="k", label="height")
    ax_com.set_ylabel("centre of mass height (m)")
    ax_speed.plot(t, cols["com_speed_y"], color="k", label="vertical (up +)")
    ax_speed.plot(t, cols["com_speed_x"], color="tab:blue", label="horizontal (forwards +)")
    ax_speed.axhline(0.0, color="grey", lw=0.6)
    ax_speed.set_ylabel("centre of mass speed (m/s)")
    if events is not None:
        _event_lines([ax_grf], events, apex=False)
        _event_lines([ax_com, ax_speed], events, apex=True)
        if events.take_off is not None:
            i = int(np.argmin(np.abs(t - events.take_off)))
            ax_speed.plot(t[i], cols["com_speed_y"][i], "o", color="tab:red")
            ax_speed.annotate(f"{cols['com_speed_y'][i]:.2f} m/s", (t[i], cols["com_speed_y"][i]),
                              xytext=(-6, 4), textcoords="offset points", ha="right",
                              fontsize="small", color="tab:red")
            j = int(np.argmax(cols["com_y"]))
            ax_com.plot(t[j], cols["com_y"][j], "o", color="tab:green")
            ax_com.annotate(f"apex {cols['com_y'][j]:.3f} m", (t[j], cols["com_y"][j]),
                            xytext=(-10, -14), textcoords="offset points", ha="right",
                            fontsize="small", color="tab:green")
    for ax in axes[0]:
        ax.grid(alpha=0.3)
    _legends(axes[0], "small")
    for row, joint in enumerate(acting, start=1):
        _joint_row(axes[row], model, joint, [(f"simulated ({result.method})", cols, "-", 1.5)])
        _legends(axes[row], "small")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    for row in axes[:-1]:
        for ax in row:
            ax.tick_params(labelbottom=False)
    title = f"torquesim: {model.name}, {result.method}"
    if result.step:
        title += f", h = {result.step * 1e3:g} ms"
    if events is not None and events.take_off is not None:
        title += (f"; take-off {events.take_off:.3f} s, flight adds "
                  f"{events.flight_height * 100:.1f} cm")
    fig.suptitle(textwrap.fill(title, 100))
    return fig


#: Most frames an animation holds (a GIF keeps every frame in memory while it is written: about
#: 0.6 MB each at `ANIMATION_DPI`); a longer run is shown faster than real time.
MAX_FRAMES = 300
ANIMATION_DPI = 80
#: A run shorter than this (s) is played slowed down so that it lasts about this long: a jump's
#: push of 0.25 s in real time is 6 frames at 25 per second.
MIN_PLAYING_TIME = 5.0
#: The slow-motion factors an animation uses (the smallest that reaches `MIN_PLAYING_TIME`).
SLOW_MOTION = (1, 2, 5, 10, 20, 50, 100)


def animation_times(duration: float, fps: int) -> tuple[np.ndarray, float]:
    """The simulated instants an animation shows (s) and its playing speed (× real time):
    real time for a run of `MIN_PLAYING_TIME` or more, slowed by the smallest of
    `SLOW_MOTION` that makes a shorter run last that long, and at most `MAX_FRAMES` frames
    (a long run then plays faster than real time)."""
    slow = next((f for f in SLOW_MOTION if duration * f >= MIN_PLAYING_TIME), SLOW_MOTION[-1])
    times = np.arange(0.0, duration + 1e-12, 1.0 / (fps * slow))
    if times.size > MAX_FRAMES:
        times = np.linspace(0.0, duration, MAX_FRAMES)
        return times, (times[1] - times[0]) * fps
    return times, 1.0 / slow


def animate_result(result, path, *, fps: int = 25) -> None:
    """Write the motion as a stick-figure animation (GIF by Pillow) at ``fps`` frames per
    second, played at the speed of `animation_times` (slowed down for a short run such as a
    jump, sped up for a long one; the title says which), each frame with the time and every
    joint's angle in degrees; for a body on the ground also the ground line, the outline of
    a segment through its points (the foot's heel and toe), the centre of mass and the total
    ground reaction force as an arrow at the centre of pressure (`FORCE_ARROW_SCALE` m per
    body weight, with a key)."""
    from matplotlib import animation
    from matplotlib.collections import LineCollection

    model = result.model
    times, speed = animation_times(float(result.time[-1]), fps)
    coords = np.column_stack([np.interp(times, result.time, result.states[:, i])
                              for i in range(model.n_coordinates)])
    q = coords[:, model.n_base:]
    lines = segment_lines(model, coords)
    where = model.kinematics(coords)
    fig = _figure(figsize=(5.0, 5.0))
    ax = fig.add_subplot()
    xy = lines.reshape(-1, 2)
    if model.contacts:
        columns = result.columns()
        weight = model.weight
        grf = FORCE_ARROW_SCALE * np.column_stack([
            np.interp(times, result.time, columns[name]) for name in ("grf_x", "grf_y")
        ]) / max(weight, 1e-12)
        cop = np.interp(times, result.time, np.nan_to_num(columns["cop_x"]))
        ax.axhline(0.0, color="tab:brown", lw=2)
        xy = np.vstack([xy, np.column_stack([cop + grf[:, 0], grf[:, 1]])])
    low, high = xy.min(axis=0), xy.max(axis=0)
    middle, span = 0.5 * (low + high), 0.6 * max(high - low) + 0.05
    ax.set_xlim(middle[0] - span, middle[0] + span)
    ax.set_ylim(middle[1] - span, middle[1] + span)
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    bones = LineCollection(lines[0], colors="k", linewidths=3, capstyle="round")
    ax.add_collection(bones)
    shapes = outlines(model)
    feet = LineCollection([], colors="k", linewidths=1.5)
    ax.add_collection(feet)
    (joints,) = ax.plot([], [], "o", color="tab:blue", ms=6)
    artists = [bones, feet, joints]
    if model.points:
        (marks,) = ax.plot([], [], "^", color="tab:orange", ms=6)
        artists.append(marks)
    if model.base == "free":
        (com,) = ax.plot([], [], "o", ms=9, mfc="white", mec="tab:red", mew=2)
        artists.append(com)
    if model.contacts:
        arrow = ax.quiver([0.0], [0.0], [0.0], [0.0], angles="xy", scale_units="xy", scale=1,
                          color="tab:green", width=0.012)
        ax.quiverkey(arrow, 0.95, 0.06, FORCE_ARROW_SCALE, "ground force:\n1 body weight",
                     angle=90, labelpos="W", coordinates="axes",
                     fontproperties={"size": "small"})
        artists.append(arrow)
    label = ax.text(0.02, 0.97, "", transform=ax.transAxes, va="top", fontsize="small")
    artists.append(label)
    names = [j.coordinate for j in model.joints]

    def frame(i):
        bones.set_segments(lines[i])
        if shapes:
            feet.set_segments(outline_polygons(model, {k: v[i] for k, v in where.items()}))
        joints.set_data(where["joints"][i, :, 0], where["joints"][i, :, 1])
        if model.points:
            marks.set_data(where["points"][i, :, 0], where["points"][i, :, 1])
        if model.base == "free":
            com.set_data([where["com"][i, 0]], [where["com"][i, 1]])
        if model.contacts:
            arrow.set_offsets([[cop[i], 0.0]])
            arrow.set_UVC([grf[i, 0]], [grf[i, 1]])
        label.set_text(f"t = {times[i]:.3f} s\n" + "\n".join(
            f"{name} {np.degrees(angle):.1f}°" for name, angle in zip(names, q[i], strict=True)))
        return artists

    pace = ("real time" if abs(speed - 1.0) < 1e-9 else
            f"{speed:.3g}× real time (slow motion)" if speed < 1.0 else
            f"{speed:.3g}× real time")
    ax.set_title(f"{result.model.name}, {result.method}, {pace}", fontsize="medium")
    fig.canvas.draw()  # lay the figure out once: every frame has the same layout
    fig.set_layout_engine("none")
    movie = animation.FuncAnimation(fig, frame, frames=len(times), blit=True)
    import os
    from pathlib import Path

    import matplotlib.pyplot as plt

    from .errors import ModelError

    path = Path(path)
    # Pillow picks the format from the name: the temporary file keeps the .gif suffix
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.gif")
    try:
        movie.save(tmp, writer=animation.PillowWriter(fps=fps), dpi=ANIMATION_DPI)
        os.replace(tmp, path)
    except OSError as exc:
        raise ModelError("--animate", f"cannot write {str(path)!r}: "
                         f"{exc.strerror or exc}") from None
    finally:
        tmp.unlink(missing_ok=True)
        plt.close(fig)


def _figure(figsize):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt.figure(figsize=figsize, layout="constrained")


def _channel_row(axes, cols, channels, weight):
    """The fit figure's row of ground reaction forces and centre of mass: simulated (solid)
    and target (dashed), then the residuals in % of body weight and cm."""
    t = cols["time"]
    kinds = (("grf", "ground reaction force (N)", 100.0 / weight, "% body weight"),
             ("com", "centre of mass (m)", 100.0, "cm"))
    for k, (prefix, label, scale, unit) in enumerate(kinds):
        ax, ax_res = axes[k], axes[2 + k] if len(axes) > 3 else None
        names = [c for c in channels if c.startswith(prefix)]
        if not names:
            ax.set_axis_off()
            if ax_res is not None:
                ax_res.set_axis_off()
            continue
        worst = []
        for i, name in enumerate(names):
            tt, goal = channels[name]
            color = f"C{i}"
            ax.plot(t, cols[name], color=color, label=f"{name} simulated")
            ax.plot(tt, goal, ls=(0, (4, 3)), color=color, lw=1.6, label=f"{name} target")
            residual = (np.interp(tt, t, cols[name]) - goal) * scale
            worst.append(f"{name} RMS {float(np.sqrt(np.mean(residual**2))):.3g}")
            if ax_res is not None:
                ax_res.plot(tt, residual, color=color, label=name)
        ax.set_ylabel(label)
        ax.legend(loc="best", fontsize="small")
        if ax_res is not None:
            ax_res.axhline(0.0, color="grey", lw=0.8)
            ax_res.set_ylabel(f"residual ({unit})")
            ax_res.set_title(", ".join(worst), fontsize="medium")
            ax_res.legend(loc="best", fontsize="small")
    for ax in axes:
        ax.grid(alpha=0.3)


def _figure_grid(nrows: int, ncols: int, size):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(nrows, ncols, figsize=size, sharex=True, squeeze=False,
                             constrained_layout=True)
    return fig, axes


def figure_png(fig, dpi: int = 110) -> bytes:
    """``fig`` as PNG bytes (for pages that inline their figures); closes the figure."""
    import io

    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    return buf.getvalue()


def save_figure(fig, path, field: str = "plot") -> None:
    """Save a figure atomically (format from the extension) and close it; a path that cannot
    be written is a ModelError under ``field``."""
    from pathlib import Path

    import matplotlib.pyplot as plt

    from .io.atomic import write_atomic

    fmt = Path(path).suffix.lstrip(".").lower() or "png"
    try:
        write_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=120), field)
    finally:
        plt.close(fig)


def plot_comparison(start, optimum, *, title: str = "", poses: int = 8):
    """Start and optimum of an optimisation side by side (``start``, ``optimum``: results of
    one model's two activation sets): per joint that has units its angle (deg), the net
    muscle torque and each unit's signed torque (N·m, the joint's positive motion +) and the
    units' activations, the optimum solid
    and the start dashed. A body on the ground adds a row with the vertical ground reaction
    force (body weights), the centre-of-mass height (m) and ``poses`` stick figures of each run over
    time (light to dark)."""
    model = optimum.model
    ground = bool(model.contacts)
    acting = joints_with_units(model)
    n = len(acting)
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    rows = n + ground
    fig, axes = plt.subplots(rows, 3, figsize=(13.5, 2.9 * rows + 0.8), squeeze=False,
                             constrained_layout=True)
    runs = (("start", start, (0, (4, 3)), 1.3), ("optimum", optimum, "-", 1.6))
    columns = {label: run.columns() for label, run, _, _ in runs}
    for row, joint in enumerate(acting):
        _joint_row(axes[row], model, joint,
                   [(label, columns[label], style, width) for label, _, style, width in runs])
        _legends(axes[row], "x-small")
        for ax in axes[row]:
            ax.set_xlabel("time (s)")
    if ground:
        ax_grf, ax_com, ax_pose = axes[n]
        for label, _run, style, width in runs:
            cols = columns[label]
            ax_grf.plot(cols["time"], cols["grf_y"] / model.weight, color="k", ls=style,
                        lw=width, label=label)
            ax_com.plot(cols["time"], cols["com_y"], color="k", ls=style, lw=width, label=label)
        ax_grf.axhline(1.0, color="grey", ls=":", lw=1.0, label="body weight")
        ax_grf.set_ylabel(f"vertical GRF (body weights,\n1 = {model.weight:.0f} N)")
        ax_com.set_ylabel("centre of mass height (m)")
        for ax in (ax_grf, ax_com):
            ax.set_xlabel("time (s)")
            ax.legend(loc="best", fontsize="x-small")
            ax.grid(alpha=0.3)
        gap = 0.0
        for (label, run, _style, _w), color in zip(runs, ("grey", "tab:blue"), strict=True):
            picks = np.linspace(0, run.time.size - 1, poses).astype(int)
            lines = segment_lines(model, run.states[picks][:, :model.n_coordinates])
            for k, frame in enumerate(lines):
                for seg in frame:
                    ax_pose.plot(seg[:, 0] + gap, seg[:, 1], color=color,
                                 alpha=0.25 + 0.75 * k / max(poses - 1, 1), lw=1.5)
            ax_pose.text(float(lines[..., 0].mean()) + gap, -0.08, label,
                         ha="center", va="top", color=color)
            gap += 1.0
        ax_pose.axhline(0.0, color="k", lw=0.8)
        ax_pose.set_ylim(bottom=-0.2)
        ax_pose.set_aspect("equal")
        ax_pose.set_xlabel("x (m), the optimum drawn 1 m to the right")
        ax_pose.set_ylabel("y (m)")
    fig.suptitle(textwrap.fill(title or f"torquesim optimise: {model.name}", 90))
    return fig


def plot_strength_fit(phases, parameters, *, title: str = ""):
    """The figure of a strength fit: the data and the fitted maximum voluntary torque.

    ``phases`` is a list of dicts, one per trial phase: ``label``, ``theta_cc`` (rad),
    ``omega_cc`` (rad/s), ``angle`` (joint, rad), ``torque`` (measured unit torque, N·m) and
    ``fitted`` (T_mv at the samples, N·m); ``parameters`` the fitted `TorqueGeneratorUnit`.
    Panels: torque against joint angle (data as dots, the fit as a line, one colour per
    phase); against CE velocity with T_mv at the optimal angle; the surface T_mv(θ_cc, ω_cc)
    with the samples on it; the residuals (data − fit) against CE velocity."""
    from .model.torque_generator import maximum_voluntary_torque

    fig = _figure((11.0, 8.8))
    axes = fig.subplots(2, 2)
    p = parameters.to_array()
    import matplotlib

    palette = matplotlib.colormaps["tab20"]
    for i, ph in enumerate(phases):
        color = palette(i % 20)
        angle = np.degrees(ph["angle"])
        axes[0, 0].plot(angle, ph["torque"], ".", ms=2.5, color=color, alpha=0.6)
        axes[0, 0].plot(angle, ph["fitted"], "-", color=color, lw=1.2, label=ph["label"])
        axes[0, 1].plot(np.degrees(ph["omega_cc"]), ph["torque"], ".", ms=2.5, color=color,
                        alpha=0.6)
        axes[1, 1].plot(np.degrees(ph["omega_cc"]), ph["torque"] - ph["fitted"], ".", ms=2.5,
                        color=color, alpha=0.6)
    wmax = parameters.max_velocity
    omega = np.linspace(-wmax, wmax, 401)
    peak = maximum_voluntary_torque(np.full_like(omega, parameters.optimal_angle), omega, p)
    axes[0, 1].plot(np.degrees(omega), peak, "k-", lw=1.5, label="T_mv at the optimal angle")
    theta = np.concatenate([ph["theta_cc"] for ph in phases])
    speeds = np.concatenate([ph["omega_cc"] for ph in phases])
    margin = 0.15 * max(np.ptp(speeds), 1.0)
    axes[0, 1].set_xlim(np.degrees(min(speeds.min(), 0.0) - margin),
                        np.degrees(max(speeds.max(), 0.0) + margin))
    tt, ww = np.meshgrid(np.linspace(theta.min() - 0.2, theta.max() + 0.2, 81),
                         np.linspace(min(speeds.min(), 0.0) - 0.5, max(speeds.max(), 0.0) + 0.5,
                                     81))
    surface = maximum_voluntary_torque(tt.ravel(), ww.ravel(), p).reshape(tt.shape)
    filled = axes[1, 0].contourf(np.degrees(tt), np.degrees(ww), surface, levels=15,
                                 cmap="viridis")
    fig.colorbar(filled, ax=axes[1, 0], label="T_mv (N·m)")
    axes[1, 0].plot(np.degrees(theta), np.degrees(speeds), "w.", ms=1.5)
    axes[1, 1].axhline(0.0, color="grey", lw=0.8)
    axes[0, 0].set(xlabel="joint angle (deg)", ylabel="unit torque (N·m)",
                   title="data (dots) and fit (lines) per trial")
    axes[0, 1].set(xlabel="CE velocity (deg/s, + concentric)", ylabel="unit torque (N·m)",
                   title="against CE velocity")
    axes[1, 0].set(xlabel="CE angle (deg)", ylabel="CE velocity (deg/s)",
                   title="fitted surface and the samples")
    axes[1, 1].set(xlabel="CE velocity (deg/s, + concentric)", ylabel="residual (N·m)",
                   title="data − fit")
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="outside lower center", ncols=4,
               fontsize="x-small")
    axes[0, 1].legend(fontsize="small")
    for ax in (axes[0, 0], axes[0, 1], axes[1, 1]):
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig
