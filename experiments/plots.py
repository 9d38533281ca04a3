"""Report figures (matplotlib, Agg backend, PNG): episode time histories and a bar chart of J."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from attitude_envs import quaternion  # noqa: E402
from attitude_envs.evaluation.metrics import RPM_PER_RAD_S  # noqa: E402
from attitude_envs.evaluation.trace import EpisodeTrace, StateTrace  # noqa: E402


def plot_episodes(traces: Mapping[str, EpisodeTrace], path: str | Path, title: str = "") -> Path:
    """One column per controller (label → trace), rows: eigen-axis error, 3-2-1 Euler angles,
    body rates, wheel motor torques, wheel speeds. Saved as PNG at ``path``."""
    if not traces:
        raise ValueError("traces must contain at least one episode")
    labels = list(traces)
    rows = 5
    fig, axes = plt.subplots(rows, len(labels), figsize=(5.2 * len(labels), 2.3 * rows), sharex=True, squeeze=False)
    for col, label in enumerate(labels):
        tr = traces[label]
        t = tr.time_s
        t_step = t[:-1]
        euler = np.array([quaternion.to_euler_321_deg(q) for q in tr.attitude])
        target_euler = quaternion.to_euler_321_deg(tr.target_attitude[-1])
        ax = axes[0, col]
        ax.plot(t, tr.error_angle_deg, color="k")
        ax.set_ylabel("error angle α [deg]")
        ax.set_title(label)
        ax = axes[1, col]
        for i, name in enumerate(("roll φ", "pitch θ", "yaw ψ")):
            (line,) = ax.plot(t, euler[:, i], label=name)
            ax.axhline(target_euler[i], color=line.get_color(), ls=":", lw=0.8)
        ax.set_ylabel("Euler 3-2-1 [deg]")
        ax.legend(fontsize=7, loc="best")
        ax = axes[2, col]
        for i, name in enumerate("xyz"):
            ax.plot(t, np.degrees(tr.rate_rad_s[:, i]), label=f"ω{name}")
        ax.set_ylabel("body rate [deg/s]")
        ax.legend(fontsize=7, loc="best")
        ax = axes[3, col]
        for i in range(tr.applied_nm.shape[1]):
            ax.step(t_step, tr.applied_nm[:, i], where="post", label=f"wheel {i + 1}")
        ax.set_ylabel("motor torque [N·m]")
        ax.legend(fontsize=7, loc="best", ncol=2)
        ax = axes[4, col]
        for i in range(tr.wheel_speed_rad_s.shape[1]):
            ax.plot(t, tr.wheel_speed_rad_s[:, i] * RPM_PER_RAD_S, label=f"wheel {i + 1}")
        ax.set_ylabel("wheel speed [rpm]")
        ax.set_xlabel("time [s]")
        ax.legend(fontsize=7, loc="best", ncol=2)
    return _finish_grid(fig, axes, path, title)


def plot_state_histories(traces: Mapping[str, StateTrace], path: str | Path, title: str = "") -> Path:
    """Any env: one column per controller (label → :class:`StateTrace`), rows: the error angle
    (attitude envs), each true state channel (the attitude quaternion and target left out where
    the error angle stands for them), the applied actuation and the running cost J. Shared y
    axes per row, so the columns compare directly. Saved as PNG at ``path``."""
    if not traces:
        raise ValueError("traces must contain at least one episode")
    first = next(iter(traces.values()))
    skip = {"attitude", "target_attitude"} if first.error_angle_deg is not None else set()
    channels = [k for k in first.state if k not in skip]
    rows = (first.error_angle_deg is not None) + len(channels) + 2
    labels = list(traces)
    fig, axes = plt.subplots(
        rows, len(labels), figsize=(5.2 * len(labels), 2.0 * rows), sharex="col", sharey="row", squeeze=False
    )
    for col, label in enumerate(labels):
        tr, r = traces[label], 0
        t = tr.time_s
        axes[0, col].set_title(label)
        if tr.error_angle_deg is not None:
            axes[r, col].plot(t, tr.error_angle_deg, color="k")
            axes[r, col].set_ylabel("error angle [deg]")
            r += 1
        for name in channels:
            values = tr.state[name].reshape(len(t), -1)
            for i in range(values.shape[1]):
                axes[r, col].plot(t, values[:, i], lw=1.0, label=f"{name}[{i}]" if values.shape[1] > 1 else name)
            axes[r, col].set_ylabel(name, fontsize=8)
            if values.shape[1] > 1:
                axes[r, col].legend(fontsize=6, loc="best", ncol=2)
            r += 1
        for i in range(tr.applied.shape[1]):
            axes[r, col].step(t[:-1], tr.applied[:, i], where="post", lw=1.0, label=f"u[{i}]")
        axes[r, col].set_ylabel("applied actuation")
        axes[r, col].legend(fontsize=6, loc="best", ncol=2)
        axes[r + 1, col].plot(t, np.concatenate([[0.0], np.cumsum(tr.cost)]), color="k")
        axes[r + 1, col].set_ylabel("running cost J")
        axes[r + 1, col].set_xlabel("time [s]")
    return _finish_grid(fig, axes, path, title)


def plot_error_overlay(traces: Mapping[str, EpisodeTrace], path: str | Path, title: str = "") -> Path:
    """Eigen-axis error angle and its running integral (EULERINT) of several controllers on shared axes."""
    if not traces:
        raise ValueError("traces must contain at least one episode")
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6))
    for label, tr in traces.items():
        t = tr.time_s
        ax1.plot(t, tr.error_angle_deg, label=label)
        running = np.concatenate(
            [[0.0], np.cumsum(0.5 * (tr.error_angle_deg[1:] + tr.error_angle_deg[:-1]) * np.diff(t))]
        )
        ax2.plot(t, running, label=label)
    ax1.set_ylabel("error angle α [deg]")
    ax2.set_ylabel("EULERINT ∫α dt [deg·s]")
    for ax in (ax1, ax2):
        ax.set_xlabel("time [s]")
        ax.grid(True, alpha=0.3)
        ax.legend()
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_metric_bars(
    rows: Sequence[Mapping[str, Any]],
    path: str | Path,
    metric: str = "J",
    group: str = "scenario",
    label: str = "controller",
    ylabel: str = "episode cost J = ∫(xᵀQx + uᵀRu) dt",
) -> Path:
    """Grouped bar chart of the mean of ``metric`` per ``group`` (x) and ``label`` (bars)."""
    if not rows:
        raise ValueError("rows must contain at least one row")
    groups = list(dict.fromkeys(r[group] for r in rows))
    labels = list(dict.fromkeys(r[label] for r in rows))
    width = 0.8 / len(labels)
    fig, ax = plt.subplots(figsize=(max(6.0, 1.2 * len(groups) * len(labels) * 0.6 + 2), 3.8))
    x = np.arange(len(groups))
    for j, lab in enumerate(labels):
        means = [np.mean([r[metric] for r in rows if r[group] == g and r[label] == lab] or [np.nan]) for g in groups]
        ax.bar(x + (j - (len(labels) - 1) / 2) * width, means, width, label=lab)
    ax.set_xticks(x, groups)
    ax.set_ylabel(ylabel)
    ax.legend()
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)


def plot_boresight_paths(
    paths: Mapping[str, np.ndarray],
    cones: Sequence[tuple[np.ndarray, float, str]],
    path: str | Path,
    title: str = "",
) -> Path:
    """A boresight's inertial direction over an episode, one line per agent (``paths``: name →
    ``(n, 3)`` unit vectors), around keep-out cones (``cones``: inertial unit axis, half-angle in
    deg, label), on a Lambert azimuthal equal-area map of the sphere centred between the path's
    start and end (angles from the centre keep their proportions; the antipode is the rim)."""
    first = next(iter(paths.values()))
    centre = first[0] + first[-1]
    centre = centre / np.linalg.norm(centre) if np.linalg.norm(centre) > 1e-9 else first[0]
    helper = np.eye(3)[int(np.argmin(np.abs(centre)))]
    east = np.cross(helper, centre)
    east /= np.linalg.norm(east)
    north = np.cross(centre, east)

    def project(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        v = np.atleast_2d(v)
        c = np.clip(v @ centre, -1.0, 1.0)
        k = np.sqrt(2.0 / np.maximum(1.0 + c, 1e-12))
        return k * (v @ east), k * (v @ north)

    fig, ax = plt.subplots(figsize=(9.4, 6.0))
    rim = np.linspace(0.0, 2.0 * np.pi, 361)
    ax.plot(2.0 * np.cos(rim), 2.0 * np.sin(rim), color="0.7", lw=0.8)
    for axis, half_angle_deg, label in cones:
        axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        a = np.eye(3)[int(np.argmin(np.abs(axis)))]
        u = np.cross(axis, a)
        u /= np.linalg.norm(u)
        w = np.cross(axis, u)
        alpha = np.radians(half_angle_deg)
        ring = np.cos(alpha) * axis + np.sin(alpha) * (np.outer(np.cos(rim), u) + np.outer(np.sin(rim), w))
        x, y = project(ring)
        ax.fill(x, y, color="tab:red", alpha=0.25, lw=0)
        ax.plot(x, y, color="tab:red", lw=1.0)
        cx, cy = project(axis)
        ax.annotate(
            label, (cx[0], cy[0]), fontsize=8, ha="center", color="darkred", bbox={"fc": "white", "alpha": 0.7, "lw": 0}
        )
    for name, v in paths.items():
        x, y = project(np.asarray(v, dtype=float))
        ax.plot(x, y, lw=1.6, label=name)
    x, y = project(first[[0, -1]])
    ax.plot(x[0], y[0], "ko", ms=5, label="start")
    ax.plot(x[1], y[1], "k*", ms=9, label="end (first agent)")
    ax.set_aspect("equal")
    ax.set_xlim(-2.05, 2.05)
    ax.set_ylim(-2.05, 2.05)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)


def _finish_grid(fig, axes, path: str | Path, title: str) -> Path:
    """Grid lines on every panel, the title, tight layout; saved at ``path``."""
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)


def save_figure(fig, path: str | Path, dpi: int = 110) -> Path:
    """Write ``fig`` as a PNG at ``path`` (parents created) and close it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
