"""The cited flight values of ReactionWheel and AirBearing (:mod:`attitude_envs.presets.flight`).

Where a number was read in a text that quotes a datasheet rather than in the datasheet
itself, the source says "as quoted by"; "assumed:" marks a value no source gave, with the
reasoning. Units are SI; sensor noise is per sample at the sample period.
"""

from __future__ import annotations

import math

from attitude_envs.presets import Sourced
from attitude_envs.presets.flight import ARCSEC, DEG_PER_HOUR, make_table, register

# ---------------------------------------------------------------- shared hardware
_STIM300 = "Safran Sensonor STIM300 datasheet (rev. 9, as quoted by NavToolkit's stim300_model)"
_HE5AS = "Terma HE-5AS star tracker on CryoSat (ESA/GCMD instrument description)"
_HR16 = "Honeywell HR16 wheel as modelled in Basilisk's simIncludeRW.py (AVSLab)"
_FPW = "Franklin, Powell & Workman 1998, Digital Control of Dynamic Systems (3rd ed.), computation delay"

#: the gyro's output averaged over one 0.1 s control period: ARW / √(0.1 s)
_GYRO_STIM300 = {
    "noise_std": Sourced(
        0.15 * math.radians(1.0) / 60.0 / math.sqrt(0.1),
        f"{_STIM300}: angle random walk 0.15 °/√h = 4.36e-5 rad/√s, averaged over 0.1 s",
    ),
    "bias_walk_std": Sourced(
        1e-7,
        "assumed: no datasheet gives the rate random walk; √3 · 0.5 °/h bias instability / √(1000 s) "
        "(the Allan deviation's rate-random-walk slope from its minimum at about 1000 s)",
    ),
    "initial_bias_std": Sourced(
        1.0 * DEG_PER_HOUR,
        "assumed: residual turn-on bias after ground calibration, 1 °/h (twice the STIM300's 0.5 °/h "
        "bias instability; its uncalibrated bias range is ±250 °/h)",
    ),
}
_TACHOMETER = {
    "noise_std": Sourced(
        0.05, "assumed: an encoder of about 1 rpm (0.1 rad/s) quantization, taken as 0.05 rad/s white noise"
    ),
}
_WHEEL_ACTUATORS = {
    "lag_s": Sourced(
        0.02,
        "assumed: a torque loop between the 2 ms wheel delay of Sci. Rep. 14 (2024) s41598-024-65807-6, "
        "Table 3, and the 10 ms dead time of the Wittenstein cyber reaction wheel 2 model "
        "(planning guide 5022-D060586 rev. 02, §2.1.4.2)",
    ),
    "resolution": Sourced(1e-5 / 0.2, f"{_HR16}: minimum torque 1e-5 N·m of its 0.2 N·m, as a fraction of the limit"),
    "coulomb": Sourced(5e-4 / 0.2, f"{_HR16}: Coulomb friction 5e-4 N·m of its 0.2 N·m, as a fraction of the limit"),
    "viscous": Sourced(
        5e-4 / 0.2 / (6000.0 * math.pi / 30.0),
        "assumed: viscous drag equal to the Coulomb friction at the HR16's 6000 rpm, per rad/s "
        "(Bialke 1998, AAS 98-063, models both; its numbers were not available)",
    ),
}
_INERTIA = {
    "inertia_moment": Sourced(
        0.05,
        "assumed: ±5 % on each principal moment, a design-phase mass-properties tolerance (a measured "
        "inertia is better than 1 %: SAWE paper 1013, Error Terms for Moment of Inertia Measurement)",
    ),
    "inertia_axis_deg": Sourced(2.0, "assumed: principal axes within 2° (design-phase mass properties)"),
}
_MISALIGNMENT = {
    "wheel_misalignment_deg": Sourced(0.5, "assumed: a wheel mounting tolerance of 0.5° per spin axis"),
}
_DELAY = Sourced(1, f"{_FPW}: the command computed from sample k acts from sample k + 1")
_WHEEL_GAIN = Sourced(
    0.05, "assumed: ±5 % motor torque constant (scale factor) of a brushless wheel motor over temperature"
)

register(
    "ReactionWheel",
    make_table(
        "ReactionWheel",
        sensors={
            "gyro": _GYRO_STIM300,
            "star_tracker": {
                "noise_std": Sourced(
                    16.0 * ARCSEC, f"{_HE5AS}: 16″ about boresight (3.2″ across), applied on every axis"
                ),
                "period_s": Sourced(1.0 / 1.7, f"{_HE5AS}: 1.7 Hz update"),
            },
            "tachometer": _TACHOMETER,
        },
        actuators=_WHEEL_ACTUATORS,
        delay_steps=_DELAY,
        gain_tolerance=_WHEEL_GAIN,
        plant=_INERTIA | _MISALIGNMENT,
    ),
)

_DSP1750 = "KVH DSP-1750 fibre-optic gyro manual (as quoted by University of Toronto BIT course files)"
register(
    "AirBearing",
    make_table(
        "AirBearing",
        sensors={
            "gyro": {
                "noise_std": Sourced(
                    3.9e-6 / math.sqrt(0.01), f"{_DSP1750}: ARW 0.8 °/h/√Hz = 3.9e-6 rad/√s, at 100 Hz"
                ),
                "bias_walk_std": Sourced(1e-8, "assumed: √3 · 0.05 °/h bias instability / √(1000 s)"),
                "initial_bias_std": Sourced(10.0 * DEG_PER_HOUR, f"{_DSP1750}: turn-on offset about 10 °/h"),
            },
            "star_tracker": {  # on an air bearing the attitude reference is an AHRS or motion capture
                "noise_std": Sourced(
                    math.radians(0.1),
                    "assumed: 0.1° of a VN-100-class AHRS (the RAMBO testbed, engrXiv 10.31224/7342, flew one "
                    "and reports ±0.5° steady-state error)",
                ),
                "period_s": Sourced(0.02, "assumed: a 50 Hz attitude output"),
            },
            "tachometer": _TACHOMETER,
        },
        actuators=_WHEEL_ACTUATORS,
        delay_steps=_DELAY,
        gain_tolerance=_WHEEL_GAIN,
        plant=_INERTIA
        | _MISALIGNMENT
        | {
            "offset_torque_nm": Sourced(
                85.0 * 9.81 * 10e-6,
                "assumed: a 10 µm residual centre-of-mass offset per axis after automatic balancing "
                "(RAMBO, engrXiv 10.31224/7342, reports [0.08, 0.12, −27.6] µm), times m g of the 85 kg platform",
            ),
        },
    ),
)
