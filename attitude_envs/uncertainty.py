"""Inertia uncertainty: the true plant may differ from the nominal model.

Configuration (plain dict, validated once):

* ``None`` — the true inertia is the nominal one;
* ``{"kind": "fixed", "inertia_kg_m2": 3x3}`` — a fixed true inertia;
* ``{"kind": "random", "moment_scale": 0.1, "axis_angle_deg": 10.0}`` — per episode, each
  principal moment scaled by ``1 + U(−s, s)`` (redrawn until the triangle inequality holds)
  and the principal axes rotated by a random rotation of up to ``axis_angle_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from attitude_envs import quaternion, validation

_KINDS = ("fixed", "random")


@dataclass(frozen=True)
class InertiaUncertainty:
    kind: str
    inertia_kg_m2: np.ndarray | None = None
    moment_scale: float = 0.1
    axis_angle_deg: float = 10.0

    @classmethod
    def from_config(cls, config: dict | None) -> InertiaUncertainty | None:
        if config is None:
            return None
        if not isinstance(config, dict):
            raise ValueError(f"inertia_uncertainty must be a dict or None, got {config!r}")
        kind = validation.choice("inertia_uncertainty.kind", config.get("kind"), _KINDS)
        unknown = set(config) - {"kind", "inertia_kg_m2", "moment_scale", "axis_angle_deg"}
        if unknown:
            raise ValueError(f"inertia_uncertainty has unknown keys {sorted(unknown)}")
        if kind == "fixed":
            return cls(kind, validation.inertia("inertia_uncertainty.inertia_kg_m2", config.get("inertia_kg_m2")))
        scale = validation.in_range(
            "inertia_uncertainty.moment_scale", config.get("moment_scale", 0.1), 0.0, 1.0, open_high=True
        )
        angle = validation.in_range(
            "inertia_uncertainty.axis_angle_deg", config.get("axis_angle_deg", 10.0), 0.0, 180.0
        )
        return cls(kind, None, scale, angle)

    def draw(self, nominal_kg_m2: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A physically valid true inertia tensor, kg·m²."""
        if self.kind == "fixed":
            return self.inertia_kg_m2
        moments, axes = np.linalg.eigh(nominal_kg_m2)
        for _ in range(1000):
            drawn = moments * (1.0 + rng.uniform(-self.moment_scale, self.moment_scale, size=3))
            s = np.sort(drawn)
            if s[0] + s[1] >= s[2]:
                break
        else:  # pragma: no cover - only for nominal inertias at the triangle limit
            raise ValueError("inertia_uncertainty: could not draw principal moments meeting the triangle inequality")
        rot = quaternion.to_matrix(quaternion.random_within_angle(rng, self.axis_angle_deg)) @ axes
        inertia = rot @ np.diag(drawn) @ rot.T
        return 0.5 * (inertia + inertia.T)
