"""Figures. Plot functions take results and return Matplotlib figures; nothing here computes."""

from __future__ import annotations

import textwrap

import numpy as np


def plot_result(result, *, target=None):
    """Per joint (one row each): the joint angle (deg), each unit's torque at the joint with
    its sign (d·T: flexors +, extensors −) and the net muscle torque (N·m, flexion +), and its
    units' activations. With a ``target``, a fourth panel per scored joint shows the residual
    (simulated − target, deg) with its RMS and maximum.

    ``target`` is an optional (time, angle rad) pair drawn over the first joint's angle, or a
    dict joint name → (time, angle rad).
    """
    cols = result.columns()
    model = result.model
    t = cols["time"]
    n = model.n_joints
    targets = target if isinstance(target, dict) else (
        {model.joints[0].name: target} if target is not None else {})
    ncols = 4 if targets else 3
    fig, axes = _figure_grid(n, ncols, (4.4 * ncols, 2.9 * n + 0.8))
    for row, joint in enumerate(model.joints):
        ax_angle, ax_torque, ax_act = axes[row][:3]
        angle = np.degrees(cols[joint.coordinate])
        ax_angle.plot(t, angle, color="k", label=f"simulated ({result.method})")
        if joint.name in targets:
            tt, goal = targets[joint.name]
            ax_angle.plot(tt, np.degrees(goal), ls=(0, (4, 3)), color="tab:red", lw=1.6,
                          label="target", zorder=3)
            residual = np.interp(tt, t, angle) - np.degrees(goal)
            ax_res = axes[row][3]
            rms, worst = float(np.sqrt(np.mean(residual**2))), float(np.max(np.abs(residual)))
            ax_res.plot(tt, residual, color="tab:red")
            ax_res.axhline(0.0, color="grey", lw=0.8)
            ax_res.set_ylabel(f"{joint.name} residual (deg)")
            ax_res.set_title(f"RMS {rms:.3f}°, max {worst:.3f}°", fontsize="medium")
        elif targets:
            axes[row][3].set_axis_off()
        ax_angle.set_ylabel(f"{joint.coordinate} (deg)")
        ax_angle.legend(loc="best", fontsize="small")
        units = [u for u in model.units if u.joint == joint.name]
        for u in units:
            sign = "+" if u.direction == 1 else "−"
            ax_torque.plot(t, u.direction * cols[f"torque_{u.name}"],
                           label=f"{u.name} ({sign})")
            ax_act.plot(t, cols[f"activation_{u.name}"], label=u.name)
        ax_torque.plot(t, cols[f"torque_net_{joint.name}"], color="k", lw=1,
                       label="net")
        ax_torque.axhline(0.0, color="grey", lw=0.6)
        ax_torque.set_ylabel(f"{joint.name} torque, flexion + (N·m)")
        ax_torque.legend(loc="best", fontsize="small")
        ax_act.set_ylim(0.0, 1.05)
        ax_act.set_ylabel("activation (0–1)")
        ax_act.legend(loc="best", fontsize="small")
        for ax in axes[row]:
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    title = f"torquesim: {model.name}, {result.method}"
    if result.step:
        title += f", h = {result.step * 1e3:g} ms"
    fig.suptitle(textwrap.fill(title, 80))
    return fig


def _figure_grid(nrows: int, ncols: int, size):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(nrows, ncols, figsize=size, sharex=True, squeeze=False,
                             constrained_layout=True)
    return fig, axes


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
