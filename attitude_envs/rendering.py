"""Pictures of the spacecraft for ``render_mode="rgb_array"`` / ``"human"`` (matplotlib, no OpenGL).

Left: body axes (solid, x red, y green, z blue) and target axes (dashed) in the inertial
frame. Right: wheel speeds as bars, as a fraction of the speed limit.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from attitude_envs import quaternion

_COLORS = ("tab:red", "tab:green", "tab:blue")


class AttitudeRenderer:
    """Draws frames of width × height pixels; one figure reused for every frame."""

    def __init__(self, width: int = 480, height: int = 320, human: bool = False) -> None:
        dpi = 80
        self.human = human
        if human:
            import matplotlib.pyplot as plt  # heavy, and it picks a GUI backend: only for render_mode="human"

            self._plt = plt
            self.fig = plt.figure(figsize=(width / dpi, height / dpi), dpi=dpi)
        else:
            self.fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
            FigureCanvasAgg(self.fig)
        self.ax3d = self.fig.add_axes((0.0, 0.0, 0.62, 0.9), projection="3d")
        self.axbar = self.fig.add_axes((0.72, 0.15, 0.25, 0.7))

    def draw(self, q, q_target, wheel_speed_rad_s, max_wheel_speed_rad_s, t_s, rate_rad_s) -> np.ndarray | None:
        ax = self.ax3d
        ax.cla()
        body = quaternion.to_matrix(q)
        target = quaternion.to_matrix(q_target)
        for i, color in enumerate(_COLORS):
            ax.plot([0, target[0, i]], [0, target[1, i]], [0, target[2, i]], "--", color=color, lw=1.5)
            ax.plot([0, body[0, i]], [0, body[1, i]], [0, body[2, i]], "-", color=color, lw=3)
        ax.set_xlim(-1, 1)
        ax.set_ylim(-1, 1)
        ax.set_zlim(-1, 1)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_zticks([])
        err = np.degrees(quaternion.error_angle_rad(q, q_target))
        self.fig.suptitle(
            f"t = {t_s:6.1f} s   error = {err:5.1f}°   |ω| = {np.linalg.norm(rate_rad_s):.3f} rad/s", fontsize=9, y=0.97
        )
        bar = self.axbar
        bar.cla()
        limit = (
            max_wheel_speed_rad_s if np.isfinite(max_wheel_speed_rad_s) else max(1.0, np.max(np.abs(wheel_speed_rad_s)))
        )
        frac = np.asarray(wheel_speed_rad_s) / limit
        bar.bar(np.arange(1, len(frac) + 1), frac, color="tab:gray")
        bar.set_ylim(-1.05, 1.05)
        bar.axhline(0.0, color="k", lw=0.5)
        bar.set_xlabel("wheel", fontsize=8)
        bar.set_ylabel("speed / limit", fontsize=8)
        bar.tick_params(labelsize=7)
        self.fig.canvas.draw()
        frame = np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()
        if self.human:
            self._plt.pause(0.001)
            return None
        return frame

    def close(self) -> None:
        if self.human:
            self._plt.close(self.fig)
