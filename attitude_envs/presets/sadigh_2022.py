"""Presets of Magnetorquer-v0: the nano-satellite with three magnetorquers and one y-axis
reaction wheel of Sadigh, Kashaninia & Dehghan (2022), fault-tolerant adaptive modified
nonsingular fast terminal sliding-mode control (AMNFTSMC).

* ``sadigh-2022`` (the env's default): the paper's spacecraft, orbit and actuators, healthy;
* ``sadigh-2022-faults``: the same with the paper's simultaneous magnetorquer faults of
  eq. (40), ``E = diag(0.9, 0.7, 0.6)`` from t = 50 s on (the wheel stays healthy).

The paper's time-varying inertia (eq. 35) and external disturbance (eq. 39) are the env's
``time_varying_inertia="paper"`` and ``disturbance="paper"`` options (on by default; None
switches either off): :data:`TIME_VARYING_INERTIA` holds the eq. (35) coefficients, the
compiled step (:mod:`attitude_envs.plants.magnetorquer_kernels`) those of eq. (39).
"""

from __future__ import annotations

import numpy as np

from attitude_envs.plants.magnetic_field import DIPOLE_STRENGTH_T_M3
from attitude_envs.plants.magnetorquer import E_Y
from attitude_envs.presets import Preset, Sourced, register

PAPER = "Sadigh et al. 2022"
CITATION = (
    "M. Sadigh, A. Kashaninia, S. M. M. Dehghan, Fault-tolerant attitude control of a nano-satellite "
    "with magnetorquers and a reaction wheel (adaptive modified nonsingular fast terminal sliding mode), "
    "Journal of Control 15(4), 2022, DOI 10.52547/joc.15.4.49"
)

_WHEEL_INERTIA_KG_M2 = 50e-6
# J_t = J_s + J_w e_y e_yᵀ: the whole spacecraft with the wheel's spin inertia, as the env takes it
_INERTIA_KG_M2 = np.diag([0.951, 0.97, 0.946]) + _WHEEL_INERTIA_KG_M2 * np.outer(E_Y, E_Y)

#: ΔJ_s(t) = 0.095 diag(sin 0.3t, 2 cos 0.2t, sin 0.1t) kg·m², the env's ``time_varying_inertia="paper"``
TIME_VARYING_INERTIA = Sourced(
    {"amplitude_kg_m2": [0.095, 0.19, 0.095], "frequency_rad_s": [0.3, 0.2, 0.1], "phase_rad": [0.0, np.pi / 2, 0.0]},
    f"{PAPER}, eq. 35",
)

_VALUES = {
    "inertia_kg_m2": Sourced(
        _INERTIA_KG_M2, f"{PAPER}, eq. 34 (J_s = diag(0.951, 0.97, 0.946)) plus the wheel's J_w on y (J_t)"
    ),
    "wheel_inertia_kg_m2": Sourced(_WHEEL_INERTIA_KG_M2, f"{PAPER}, Table 1"),
    "max_dipole_am2": Sourced(0.5, f"{PAPER}, Table 1 and Assumption 3"),
    "max_wheel_torque_nm": Sourced(2.3e-4, f"{PAPER}, Table 1 and Assumption 3"),
    "max_wheel_momentum_nms": Sourced(
        40.0, f"{PAPER}, Table 1 (40 N·m·s as printed, inactive in practice; 0.04 is the likely intended value)"
    ),
    "orbit": Sourced(
        {
            "model": "keplerian",
            "apogee_altitude_km": 1250.0,
            "perigee_altitude_km": 311.0,
            "inclination_deg": 69.5,
            "raan_deg": 0.0,
            "arg_perigee_deg": 0.0,
            "mean_anomaly_deg": "random",
        },
        f"{PAPER}, Table 1 (apogee, perigee, inclination); assumed: RAAN and argument of perigee 0 "
        "(not printed), the start on the orbit drawn per episode",
    ),
    "reference": Sourced(
        {"delta_deg": [10.0, 20.0, 10.0], "t_final_s": 1200.0, "start_deg": [0.0, 0.0, 0.0]},
        "assumed: the smooth bang-bang 3-2-1 profile of Sadigh et al. 2022, eqs. 36–38, prints no "
        "parameters; a 10°/20°/10° slew from rest at zero over 1200 s",
    ),
    "field_model": Sourced(
        "dipole", f"{PAPER}, eq. 9 (the axial dipole, evaluated at the actual position in the LVLH frame)"
    ),
    "dipole_strength_t_m3": Sourced(DIPOLE_STRENGTH_T_M3, "assumed: the paper prints no μ_e; Wertz's 7.96e15 T·m³"),
    "control_dt_s": Sourced(0.1, "assumed: the paper prints no step size; 0.1 s with zero-order-hold control"),
    "Q": Sourced(
        np.diag([1.0] * 3 + [1e3] * 3),
        "assumed: the paper defines no cost; 1 per unit q_e², 1e3 per (rad/s)² of ω_e "
        "(a 0.01 attitude error and 1e-3 N·m of torque weigh alike)",
    ),
    "R": Sourced(1e4 * np.eye(3), "assumed: 1e4 per (N·m)² of body control torque (see Q)"),
}

SADIGH_2022 = register(
    Preset(
        name="sadigh-2022",
        env="Magnetorquer-v0",
        description="nano-satellite, 3 magnetorquers + 1 wheel on y, elliptic 311×1250 km orbit: tracking a slew",
        citation=CITATION,
        default=True,
        values=_VALUES,
    )
)

SADIGH_2022_FAULTS = register(
    Preset(
        name="sadigh-2022-faults",
        env="Magnetorquer-v0",
        description="sadigh-2022 with the paper's magnetorquer faults: E = diag(0.9, 0.7, 0.6) from t = 50 s",
        citation=CITATION,
        values={
            **_VALUES,
            "faults": Sourced(
                [
                    {"kind": "loss_of_effectiveness", "index": i, "value": v, "onset_s": 50.0}
                    for i, v in enumerate((0.1, 0.3, 0.4))
                ],
                f"{PAPER}, eq. 40 (magnetorquer effectiveness diag(0.9, 0.7, 0.6) for t > 50 s; "
                "assumed: the wheel healthy, the paper gives no wheel fault)",
            ),
        },
    )
)
