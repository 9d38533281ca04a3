"""SingleAxis-v0: the env of :mod:`example_plant`, written on the suite's shared base.

Everything the suite's envs share — presets, actuator and sensor faults, ``fault_hint``,
the info contract (truth vs. measured) — comes from
:class:`attitude_envs.envs.base.AttitudeEnv`; this module holds only what is the plant's:
its spaces, its state and its step.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from example_plant import SingleAxisModel, step
from gymnasium import spaces

from attitude_envs import validation
from attitude_envs.cost import QuadraticCost
from attitude_envs.envs.base import AttitudeEnv
from attitude_envs.evaluation.success import FINAL_STATE_FRACTION
from attitude_envs.presets import Preset, Sourced, register
from attitude_envs.sensors import Channel

register(
    Preset(
        name="demo",
        env="SingleAxis-v0",
        description="a 10 kg·m² single-axis test spacecraft",
        citation="none: a test plant",
        default=True,
        values={
            "inertia_kg_m2": Sourced(10.0, "assumed: a small spacecraft"),
            "wheel_inertia_kg_m2": Sourced(0.01, "assumed: a small wheel"),
            "max_torque_nm": Sourced(0.1, "assumed: a small wheel motor"),
            "target_rad": Sourced(0.5, "assumed: a 29° slew"),
        },
    )
)


class SingleAxisEnv(AttitudeEnv):
    """Single-axis slew with one reaction wheel (test plant).

    Observation ``[θ − θ_T (rad), ω (rad/s)]`` (+ fault flags with ``fault_hint``); action
    the normalized wheel torque in [-1, 1] (``u = a · max_torque_nm``, N·m); reward
    ``−∫ (xᵀQx + uᵀRu) dt`` over the step; episode truncated at ``episode_duration_s``.
    """

    env_name = "SingleAxis-v0"
    default_preset = "demo"
    metadata = {"render_modes": []}
    success_metric = FINAL_STATE_FRACTION  # how campaigns judge an episode (attitude_envs.evaluation.success)

    def __init__(
        self,
        preset: str | None = "demo",
        inertia_kg_m2: float | None = None,
        wheel_inertia_kg_m2: float | None = None,
        max_torque_nm: float | None = None,
        target_rad: float | None = None,
        control_dt_s: float = 0.1,
        episode_duration_s: float = 20.0,
        faults: list[dict] | None = None,
        sensors: dict | None = None,
        fault_hint: bool = False,
        render_mode: str | None = None,
    ) -> None:
        cfg = self._configure(preset, locals())
        self.model = SingleAxisModel(
            validation.positive("inertia_kg_m2", cfg["inertia_kg_m2"]),
            validation.positive("wheel_inertia_kg_m2", cfg["wheel_inertia_kg_m2"]),
            validation.positive("max_torque_nm", cfg["max_torque_nm"]),
            QuadraticCost.build(np.diag([10.0, 1.0]), np.array([[1.0]]), 2, 1),
            validation.positive("control_dt_s", cfg["control_dt_s"]),
        )
        self.episode_duration_s = validation.positive("episode_duration_s", cfg["episode_duration_s"])
        self.target_rad = float(validation.finite_array("target_rad", cfg["target_rad"], ()))
        self._init_layers(
            n_actuators=1,
            actuator_limits=self.model.max_torque_nm,
            channels=[Channel("angle", 1, units="rad"), Channel("gyro", 1, units="rad/s")],
            faults=faults,
            sensors=sensors,
            fault_hint=fault_hint,
        )
        low, high = self._hint_bounds(np.array([-10.0, -10.0]), np.array([10.0, 10.0]))
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        if render_mode is not None:
            raise ValueError(f"render_mode must be None for SingleAxis-v0, got {render_mode!r}")
        self.render_mode = None
        self._y = np.zeros(3)
        self._t = 0.0
        self._steps = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = validation.reset_options(options, {"faults"})
        self._y = np.array([0.0, self.np_random.uniform(-0.01, 0.01), 0.0])
        self._t, self._steps = 0.0, 0
        self._reset_layers(self.np_random, options)
        measured = self._measure()
        return self._observe(measured), self._info(measured, np.zeros(1), np.zeros(1), 0.0)

    def step(self, action):
        commanded = np.clip(validation.action(action, 1), -1.0, 1.0) * self.model.max_torque_nm
        applied = self._deliver(commanded, self._t)
        self._y, cost = step(self._y, float(applied[0]), self.model, self.target_rad, 2)
        self._steps += 1
        self._t = self._steps * self.model.control_dt_s
        measured = self._measure()
        truncated = self._t >= self.episode_duration_s - 1e-9
        info = self._info(measured, commanded, applied, cost)
        return self._observe(measured), -cost, False, truncated, info

    def _measure(self) -> dict[str, float]:
        truth = {"angle": self._y[:1], "gyro": self._y[1:2]}
        if self.sensor_layer.enabled:
            truth = self.sensor_layer.measure(truth, self._t)
        return {"angle_rad": float(truth["angle"][0]), "rate_rad_s": float(truth["gyro"][0])}

    def _observe(self, measured: dict[str, float]) -> np.ndarray:
        obs = np.array([measured["angle_rad"] - self.target_rad, measured["rate_rad_s"]])
        return self._with_hint(obs, self._t)

    def _info(self, measured, commanded, applied, cost: float) -> dict:
        state = {"angle_rad": float(self._y[0]), "rate_rad_s": float(self._y[1])}
        truth = {"state": state, "applied": applied.copy(), "faults": self._fault_truth(self._t)}
        return self._make_info(truth=truth, measured=measured, cost=cost, time_s=self._t, commanded=commanded)
