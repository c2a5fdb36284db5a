"""Figures. Plot functions take results and return Matplotlib figures; nothing here computes."""

from __future__ import annotations

import numpy as np


def _figure(nrows: int, height: float):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(nrows, 1, figsize=(8, height), sharex=True, constrained_layout=True)
    return fig, np.atleast_1d(axes)


def plot_result(result, *, target=None):
    """Elbow angle (deg), unit and net torques (N·m) and activations over time.

    ``target`` is an optional (time, angle rad) pair drawn over the angle.
    """
    cols = result.columns()
    t = cols["time"]
    fig, (ax_angle, ax_torque, ax_act) = _figure(3, 8.0)
    ax_angle.plot(t, np.degrees(cols["theta"]), color="k", label=f"simulated ({result.method})")
    if target is not None:
        ax_angle.plot(target[0], np.degrees(target[1]), "--", color="tab:red", label="target")
    ax_angle.set_ylabel("elbow flexion (deg)")
    ax_angle.legend(loc="best", fontsize="small")
    ax_torque.plot(t, cols["torque_flexor"], color="tab:blue", label="flexor")
    ax_torque.plot(t, cols["torque_extensor"], color="tab:orange", label="extensor")
    ax_torque.plot(t, cols["torque_net"], color="k", lw=1, label="net (flexion +)")
    ax_torque.set_ylabel("torque (N·m)")
    ax_torque.legend(loc="best", fontsize="small")
    ax_act.plot(t, cols["activation_flexor"], color="tab:blue", label="flexor")
    ax_act.plot(t, cols["activation_extensor"], color="tab:orange", label="extensor")
    ax_act.set_ylim(0.0, 1.05)
    ax_act.set_ylabel("activation")
    ax_act.set_xlabel("time (s)")
    ax_act.legend(loc="best", fontsize="small")
    for ax in (ax_angle, ax_torque, ax_act):
        ax.grid(alpha=0.3)
    title = f"torquesim: {result.method}"
    if result.step:
        title += f", h = {result.step * 1e3:g} ms"
    fig.suptitle(title)
    return fig


def save_figure(fig, path) -> None:
    """Save a figure atomically (format from the extension) and close it."""
    from pathlib import Path

    import matplotlib.pyplot as plt

    from .io.atomic import write_atomic

    fmt = Path(path).suffix.lstrip(".").lower() or "png"
    try:
        write_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=120))
    finally:
        plt.close(fig)
