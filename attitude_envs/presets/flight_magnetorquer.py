"""The cited flight values of Magnetorquer (:mod:`attitude_envs.presets.flight`).

A 3U–6U class CubeSat in LEO: an automotive MEMS gyro, a CubeSat star tracker, a
magnetometer that samples while the torquers are off, 8-bit PWM coil drivers and a small
wheel. Where a number was read in a text that quotes a datasheet rather than in the
datasheet itself, the source says "as quoted by"; "assumed:" marks a value no source gave,
with the reasoning. Units are SI; sensor noise is per sample at the sample period (the
0.1 s control period of ``sadigh-2022``).

Actuators are, in order, the dipoles m_x, m_y, m_z (A·m²) and the wheel torque (N·m);
resolution, Coulomb and viscous friction are fractions of each actuator's limit
(:class:`~attitude_envs.presets.flight.FlightTable`).
"""

from __future__ import annotations

import math

from attitude_envs.presets import Sourced
from attitude_envs.presets.flight import ARCSEC, DEG_PER_HOUR, make_table, register
from attitude_envs.presets.flight_gyrostat import _DELAY, _INERTIA, _TACHOMETER

_SCH16T = "Murata SCH16T-K01 datasheet (Jan 2024), §3.4 Table 4"
_SAGITTA = "Arcsec Sagitta star tracker datasheet v2 (as quoted by open-source ADCS simulation codes)"
_STRABEL = (
    "Strabel et al. 2022, Quad-Mag board for CubeSat applications, Geosci. Instrum. Method. Data Syst. 11, 375–388"
)
_BLANKING = (
    "KiwiSat 3-axis magnetometer page ('Timing of Magnetometer readings must be controlled to take place "
    "between magnetorque pulses') and an open-source CubeSat flight software's magnetometer task "
    "(a 20 ms settle window per 100 ms, as quoted by its header comment)"
)
_RW0 = "NanoAvionics RW0 as modelled in Basilisk's simIncludeRW.py (AVSLab)"
_RWP015 = "BCT RWP015 as modelled in Basilisk's simIncludeRW.py (AVSLab; marked there as an estimate)"

_CONTROL_PERIOD_S = 0.1  # the control period the per-sample noise is stated at (sadigh-2022)
_WHEEL_RESOLUTION = 4.9e-5 / 3.2e-3
_WHEEL_COULOMB = 5e-5 / 4e-3
_WHEEL_SPEED_RAD_S = 6000.0 * math.pi / 30.0

_GYRO_SCH16T = {
    "noise_std": Sourced(
        4.4e-6 / math.sqrt(_CONTROL_PERIOD_S),
        f"{_SCH16T}: angle random walk 0.015 °/√h = 4.4e-6 rad/√s, averaged over the 0.1 s control period",
    ),
    "bias_walk_std": Sourced(
        1e-7,
        "assumed: no datasheet gives the rate random walk; √3 · 0.5 °/h bias instability (the SCH16T-K01's, "
        f"{_SCH16T}) / √(1000 s), the reasoning of the ReactionWheel table",
    ),
    "initial_bias_std": Sourced(
        1.0 * DEG_PER_HOUR,
        "assumed: residual turn-on bias after ground calibration, 1 °/h (twice the SCH16T-K01's 0.5 °/h "
        f"bias instability, {_SCH16T})",
    ),
}

register(
    "Magnetorquer",
    make_table(
        "Magnetorquer",
        sensors={
            "gyro": _GYRO_SCH16T,
            "star_tracker": {
                "noise_std": Sourced(
                    10.0 * ARCSEC, f"{_SAGITTA}: 10″ about boresight (2″ across), applied on every axis"
                ),
                "period_s": Sourced(0.1, f"{_SAGITTA}: 10 Hz update"),
            },
            "tachometer": _TACHOMETER,
            "magnetometer": {
                "noise_std": Sourced(
                    10e-9,
                    f"PNI RM3100, one sensor: {_STRABEL} measured 5.34 nT per axis for the average of four; "
                    "one sensor about √4 = 2 times that, ≈ 10 nT (derived)",
                ),
                "initial_bias_std": Sourced(
                    100e-9,
                    "assumed: the spacecraft's residual field after on-ground calibration, 100 nT per axis "
                    "(the low end of the usual 100–500 nT; no source found)",
                ),
                "period_s": Sourced(
                    0.1, f"assumed: one sample per 0.1 s control period, between torquer pulses ({_BLANKING})"
                ),
            },
        },
        actuators={
            "resolution": Sourced(
                (1.0 / 255.0, 1.0 / 255.0, 1.0 / 255.0, _WHEEL_RESOLUTION),
                "dipoles: assumed, an 8-bit PWM coil driver (1/255 of the limit); wheel: "
                f"{_RW0}, minimum torque 4.9e-5 N·m of its 3.2e-3 N·m, as a fraction of the limit",
            ),
            "coulomb": Sourced(
                (0.0, 0.0, 0.0, _WHEEL_COULOMB),
                f"dipoles: none (a coil has no friction); wheel: {_RWP015}, Coulomb friction 5e-5 N·m of its "
                "4e-3 N·m, as a fraction of the limit",
            ),
            "viscous": Sourced(
                (0.0, 0.0, 0.0, _WHEEL_COULOMB / _WHEEL_SPEED_RAD_S),
                "dipoles: none; wheel: assumed, viscous drag equal to the Coulomb friction at 6000 rpm "
                "(the RWP015's top speed), per rad/s, as the ReactionWheel table",
            ),
            "lag_s": Sourced(
                (0.0, 0.0, 0.0, 0.02),
                "dipoles: assumed negligible (a coil's L/R time constant is milliseconds, against a 0.1 s "
                "period); wheel: assumed 0.02 s torque loop, as the ReactionWheel table",
            ),
            "duty": Sourced(
                (0.8, 0.8, 0.8, 1.0),
                f"dipoles: torquers off 20 % of each period while the magnetometer samples ({_BLANKING}); "
                "wheel: always on",
            ),
        },
        delay_steps=_DELAY,
        gain_tolerance=Sourced(
            (0.10, 0.10, 0.10, 0.05),
            "assumed: dipole scale factor ±10 % (core-rod permeability and temperature; no datasheet number "
            "found), wheel motor torque constant ±5 % over temperature",
        ),
        plant=_INERTIA,
    ),
)
