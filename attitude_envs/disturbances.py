"""External disturbance torques in body axes, N·m, drawn from the env's RNG.

Configuration (plain dict, validated once):

* ``None`` — no disturbance;
* ``{"kind": "constant", "torque_nm": [3]}``;
* ``{"kind": "sinusoidal", "amplitude_nm": [3], "period_s": P, "phase_rad": [3] or "random"}``;
* ``{"kind": "random_walk", "std_nm_per_sqrt_s": σ, "initial_nm": [3]}`` — a Wiener
  process sampled once per control step and held over it.
"""

from __future__ import annotations

import numpy as np

from attitude_envs import validation

_KINDS = ("constant", "sinusoidal", "random_walk")
_KEYS = {
    "constant": {"kind", "torque_nm"},
    "sinusoidal": {"kind", "amplitude_nm", "period_s", "phase_rad"},
    "random_walk": {"kind", "std_nm_per_sqrt_s", "initial_nm"},
}


class Disturbance:
    """Body-frame external torque ``T_ext(t)``; :meth:`reset` and :meth:`advance` draw
    from the generator they are given, so the env's seed fixes every draw."""

    def __init__(self, config: dict) -> None:
        if not isinstance(config, dict):
            raise ValueError(f"disturbance must be a dict or None, got {config!r}")
        self.kind = validation.choice("disturbance.kind", config.get("kind"), _KINDS)
        unknown = set(config) - _KEYS[self.kind]
        if unknown:
            raise ValueError(f"disturbance ({self.kind}) has unknown keys {sorted(unknown)}")
        zeros = np.zeros(3)
        if self.kind == "constant":
            self.torque_nm = validation.finite_array("disturbance.torque_nm", config.get("torque_nm", zeros), (3,))
        elif self.kind == "sinusoidal":
            self.amplitude_nm = validation.finite_array(
                "disturbance.amplitude_nm", config.get("amplitude_nm", zeros), (3,)
            )
            self.period_s = validation.positive("disturbance.period_s", config.get("period_s", 5400.0))
            phase = config.get("phase_rad", zeros)
            self._random_phase = isinstance(phase, str)
            if self._random_phase:
                validation.choice("disturbance.phase_rad", phase, {"random"})
                phase = zeros
            self.phase_rad = validation.finite_array("disturbance.phase_rad", phase, (3,))
        else:
            self.std = validation.nonnegative("disturbance.std_nm_per_sqrt_s", config.get("std_nm_per_sqrt_s", 0.0))
            self.initial_nm = validation.finite_array("disturbance.initial_nm", config.get("initial_nm", zeros), (3,))
        self._phase = np.zeros(3)
        self._walk = np.zeros(3)

    @property
    def episode_phase_rad(self) -> np.ndarray:
        """The sinusoid's phases this episode (drawn at :meth:`reset` when ``"random"``),
        rad; a read-only view (zeros for the other kinds)."""
        view = self._phase.view()
        view.setflags(write=False)
        return view

    @property
    def random_phase(self) -> bool:
        """True when the sinusoid's phases are drawn per episode (``phase_rad="random"``)."""
        return bool(getattr(self, "_random_phase", False))

    @property
    def walk_nm(self) -> np.ndarray:
        """The random walk's current value, the torque held over this control step, N·m; a
        read-only view (zeros for the other kinds)."""
        view = self._walk.view()
        view.setflags(write=False)
        return view

    def reset(self, rng: np.random.Generator) -> None:
        if self.kind == "sinusoidal":
            self._phase = rng.uniform(0.0, 2 * np.pi, size=3) if self._random_phase else self.phase_rad
        elif self.kind == "random_walk":
            self._walk = self.initial_nm.copy()

    def advance(self, rng: np.random.Generator, dt_s: float) -> None:
        """Move a random walk one control period forward."""
        if self.kind == "random_walk":
            self._walk = self._walk + self.std * np.sqrt(dt_s) * rng.normal(size=3)

    def torque_nm_at(self, t_s: float) -> np.ndarray:
        if self.kind == "constant":
            return self.torque_nm
        if self.kind == "sinusoidal":
            return self.amplitude_nm * np.sin(2 * np.pi * t_s / self.period_s + self._phase)
        return self._walk
