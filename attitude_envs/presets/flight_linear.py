"""The cited flight values of LinearSystem (:mod:`attitude_envs.presets.flight`).

LinearSystem is an abstract plant (any ``A``, ``B``; by default the linearized satellite
of Heravi & Novinzadeh 2017): no hardware datasheet applies, so every value but the
computation delay is an assumption, with its reason.

**The state sensor** measures the whole state with white noise whose standard deviation
is a *fraction* of each entry's typical scale (one table serves every ``A``, ``B``, as the
actuator values of the other tables are fractions of the limits):
:meth:`~attitude_envs.envs.linear_system.LinearSystemEnv.state_scale` gives the scale, and
the env multiplies (:func:`state_sensor_config`). There are no actuator dynamics beyond
the delay and the scale-factor error, which is the flight error of ``B`` (each input's
column of ``B`` times a drawn gain).
"""

from __future__ import annotations

import numpy as np

from attitude_envs.presets import Sourced
from attitude_envs.presets.flight import make_table, register
from attitude_envs.presets.flight_gyrostat import _DELAY

_NOISE_FRACTION = Sourced(
    0.01,
    "assumed: white noise of 1 % of each state entry's typical scale (an abstract plant; no hardware "
    "source applies; the research notes suggest 1–5 %); a fraction, the env multiplies it by "
    "LinearSystemEnv.state_scale",
)

register(
    "LinearSystem",
    make_table(
        "LinearSystem",
        sensors={"state": {"noise_std": _NOISE_FRACTION}},
        actuators={},
        delay_steps=_DELAY,
        gain_tolerance=Sourced(
            0.05,
            "assumed: ±5 % scale factor of each input, the flight error of B (each column of B times "
            "a gain drawn per episode); an abstract plant, no hardware source applies",
        ),
    ),
)


def state_sensor_config(state_scale, noise_scale: float = 1.0) -> dict:
    """The ``sensors=`` entry of the ``state`` channel: white noise of the table's fraction
    of ``state_scale`` (one value per state entry), times ``noise_scale``."""
    scale = np.asarray(state_scale, dtype=float)
    return {"noise_std": float(_NOISE_FRACTION.value) * noise_scale * scale}
