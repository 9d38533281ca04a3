"""FuelSlosh-v0 presets ``navabi-fill-i`` … ``navabi-fill-iv`` (aliases ``"i"`` … ``"iv"``):
the planar spacecraft with two-pendulum fuel slosh of Navabi & Davoodi, "Modelling and
control of fuel slosh and its effect on spacecraft attitude" (in Persian; the journal and
year are not in our copy, which cites a 2011 paper, so ≥ 2012).

The four presets differ only in the tank lengths. Table 3 of the paper prints the five
lengths 0.05, 0.6, 0.9, 0.2, 0.1 m, but our copy lost which of a0 (rigid-fuel offset),
a1, a2 (pendulum hinges) and l1, l2 (pendulum lengths) each one is; preset ``navabi-fill-i``
(the symbol-grouped order a0, a1, a2, l1, l2, which gives the longer pendulum to the
heavier slosh mass) is the default, ``-ii`` … ``-iv`` are the other plausible assignments
(:data:`attitude_envs.plants.slosh.FILL_PRESETS`). All give slosh periods of 4–6.5 s, far
faster than the control time scale of hundreds of seconds.

This module is the one place of the paper's numbers used by the env and the baselines:
:data:`PAPER_INITIAL_STATE` (Table 4), :data:`PAPER_Q` and :data:`PAPER_R` (the LQR
weights of eqs. 30–31).
"""

from __future__ import annotations

import math

import numpy as np

from attitude_envs.plants.slosh import FILL_PRESETS, SloshParams
from attitude_envs.presets import Preset, Sourced, register

ENV = "FuelSlosh-v0"
PAPER = "Navabi & Davoodi"
CITATION = (
    "M. Navabi, A. Davoodi, Modelling and control of fuel slosh and its effect on spacecraft attitude "
    "(in Persian), Shahid Beheshti University; journal and year not in our copy (≥ 2012)"
)


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


#: Table 4: ``[v_x, v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]`` in m/s, rad, rad/s (read-only).
PAPER_INITIAL_STATE = _read_only(
    np.array([3000.0, 100.0, math.radians(2.0), 0.0, math.radians(30.0), 0.0, math.radians(-30.0), 0.0])
)
#: LQR state weight of eqs. 30–31 on ``[v_z, θ, Ω, ψ1, ψ̇1, ψ2, ψ̇2]`` (read-only).
PAPER_Q = _read_only(np.diag([1e-6, 1e-6, 1e-1, 1e-6, 1e-1, 1e-6, 1e-1]))
#: LQR input weight of eqs. 30–31 on the new inputs ``[a_z, Ω̇]`` (read-only).
PAPER_R = _read_only(1e-6 * np.eye(2))

_LENGTHS = "(a0, a1, a2, l1, l2)"

# Values shared by the four presets (only ``params`` differs).
_COMMON = {
    "Q": Sourced(PAPER_Q, f"{PAPER}, eqs. 30–31: the LQR's Q = diag(1e-6, 1e-6, 1e-1, 1e-6, 1e-1, 1e-6, 1e-1)"),
    "R": Sourced(PAPER_R, f"{PAPER}, eqs. 30–31: the LQR's R = 1e-6·I₂"),
    "initial_state": Sourced(
        PAPER_INITIAL_STATE, f"{PAPER}, Table 4: v_x 3000 m/s, v_z 100 m/s, θ 2°, ψ1 30°, ψ2 −30°, rates 0"
    ),
    "max_gimbal_deg": Sourced(30.0, "assumed: the paper gives no gimbal limit; its PD needs about 17.5°"),
    "max_moment_nm": Sourced(2000.0, "assumed: the paper gives no moment limit; its PD needs about 860 N·m"),
    "control_dt_s": Sourced(0.1, "assumed: the paper's control is continuous; a 10 Hz zero-order hold"),
    "integrator_dt_s": Sourced(
        0.05, "assumed: RK4 at 0.05 s resolves the 1–1.5 rad/s slosh modes (|λh| ≤ 0.08, step error ~1e-8)"
    ),
    "episode_duration_s": Sourced(
        1500.0, f"{PAPER}: the responses settle after about 1000 s; its comparison figures span 1500 s"
    ),
    "design_v_x_m_s": Sourced(
        3000.0, f"assumed: {PAPER} do not state the LQR's design speed; the initial v_x of Table 4"
    ),
    "max_slosh_angle_deg": Sourced(90.0, "assumed: a pendulum past 90° leaves the slosh model's range"),
    "max_pitch_rate_rad_s": Sourced(0.5, "assumed: a tumbling limit far above the paper's responses"),
    "max_pitch_angle_deg": Sourced(90.0, "assumed: a tumbling limit far above the paper's 2° start"),
}


def _fill(mapping: str, default: bool, note: str) -> Preset:
    lengths = FILL_PRESETS[mapping]
    values = dict(_COMMON)
    values["params"] = Sourced(
        SloshParams.from_fill_preset(mapping),
        f"{PAPER}, Table 3 (masses, inertias, b, d, F, hinge damping); lengths {_LENGTHS} = "
        f"{lengths} m: assumed mapping ({mapping}) of the printed values, whose symbols our copy lost",
    )
    return register(
        Preset(
            name=f"navabi-fill-{mapping}",
            env=ENV,
            description=f"planar burn with two-pendulum slosh, Table 3 lengths {_LENGTHS} = {lengths} m ({note})",
            citation=CITATION,
            values=values,
            aliases=(mapping,),
            default=default,
        )
    )


NAVABI_FILL_I = _fill("i", True, "the symbol-grouped reading; default")
NAVABI_FILL_II = _fill("ii", False, "alternative reading")
NAVABI_FILL_III = _fill("iii", False, "alternative reading")
NAVABI_FILL_IV = _fill("iv", False, "alternative reading")
