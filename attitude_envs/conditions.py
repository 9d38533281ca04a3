"""Lab and flight conditions: how much of a flying spacecraft an env models.

Every env takes ``conditions=``:

* ``"lab"`` (the default) is the papers' world. Controllers see the full state, the plant
  is exact, actuators are ideal and act at once. This is every env's behaviour without the
  keyword, bit for bit.
* ``"flight"`` turns on every feature below at the plant's cited flight values
  (:mod:`attitude_envs.presets.flight`).
* A dict turns on features one at a time, as the robustness sweeps do:

  ===============  ==========================  ==========================================
  key              value                       effect
  ===============  ==========================  ==========================================
  ``sensors``      bool or number in [0, 100]  the flight sensors (noise, bias, bias
                                               instability, sample periods); a number
                                               scales their noise, bias walk and bias
                                               spread (1: the flight values)
  ``actuators``    bool                        actuator dynamics (motor lag, command
                                               resolution, wheel friction, rate limits,
                                               duty cycle)
  ``delay_steps``  bool or integer in [0, 10]  each command acts this many control
                                               periods late (True: 1, the one-period
                                               computation delay); zeros act until then
  ``parameters``   bool or number in [0, 10]   the true plant drawn per episode within the
                                               cited tolerances times this number (True: 1)
  ``base``         ``"lab"`` or ``"flight"``   where the keys left out come from (default
                                               ``"lab"``: off)
  ===============  ==========================  ==========================================

  For example ``{"base": "flight", "delay_steps": 0}`` is flight without the delay, and
  ``{"delay_steps": 2}`` is the lab with a two-period delay.

An explicit ``sensors=`` keyword replaces the flight sensors. Flight draws (the true
plant, the actuator gains) come from a generator spawned from the env's at reset, so an
episode's start, target and faults are the lab episode's of the same seed.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass

from attitude_envs import validation

LAB, FLIGHT = "lab", "flight"
#: the keys of a ``conditions`` dict
KEYS = ("sensors", "actuators", "delay_steps", "parameters", "base")
MAX_NOISE_SCALE = 100.0
MAX_DELAY_STEPS = 10
MAX_PARAMETER_SCALE = 10.0


@dataclass(frozen=True)
class Conditions:
    """The resolved ``conditions`` of an env (every field off: the lab).

    ``sensors``: scale of the flight sensors' noise (0: sensors off, truth observed);
    ``actuators``: actuator dynamics on; ``delay_steps``: control periods of command delay;
    ``parameters``: scale of the flight parameter tolerances (0: the exact plant)."""

    sensors: float = 0.0
    actuators: bool = False
    delay_steps: int = 0
    parameters: float = 0.0

    @property
    def is_lab(self) -> bool:
        """True when nothing of the flight world is on (the env is the lab env, bit for bit)."""
        return self == Conditions()

    @property
    def name(self) -> str:
        """``"lab"``, ``"flight"`` or ``"custom"`` (the ``conditions`` column of a record)."""
        if self.is_lab:
            return LAB
        return FLIGHT if self == FLIGHT_CONDITIONS else "custom"

    def as_dict(self) -> dict:
        """The four fields as a plain dict (what ``conditions=`` accepts back)."""
        return asdict(self)

    @classmethod
    def from_config(cls, value) -> Conditions:
        """Validate a ``conditions`` keyword: None, ``"lab"``, ``"flight"``, a dict (see the
        module docstring) or a :class:`Conditions`; a ``ValueError`` names the bad key."""
        if isinstance(value, Conditions):
            return value
        if value is None or value == LAB:
            return cls()
        if value == FLIGHT:
            return FLIGHT_CONDITIONS
        if isinstance(value, str):
            raise ValueError(f"conditions must be 'lab', 'flight' or a dict of features, got {value!r}")
        if not isinstance(value, Mapping):
            raise ValueError(f"conditions must be 'lab', 'flight' or a dict with keys {list(KEYS)}, got {value!r}")
        validation.known_keys("conditions", value, KEYS)
        base_name = validation.choice("conditions['base']", value.get("base", LAB), (LAB, FLIGHT))
        base = FLIGHT_CONDITIONS if base_name == FLIGHT else cls()
        fields = base.as_dict()
        if "sensors" in value:
            fields["sensors"] = _scale("conditions['sensors']", value["sensors"], MAX_NOISE_SCALE)
        if "actuators" in value:
            fields["actuators"] = validation.flag("conditions['actuators']", value["actuators"])
        if "delay_steps" in value:
            delay = value["delay_steps"]
            if isinstance(delay, bool):
                delay = int(delay)
            fields["delay_steps"] = validation.integer("conditions['delay_steps']", delay, 0)
            if fields["delay_steps"] > MAX_DELAY_STEPS:
                raise ValueError(f"conditions['delay_steps'] must be in [0, {MAX_DELAY_STEPS}], got {delay!r}")
        if "parameters" in value:
            fields["parameters"] = _scale("conditions['parameters']", value["parameters"], MAX_PARAMETER_SCALE)
        return cls(**fields)


#: every feature at the cited flight values
FLIGHT_CONDITIONS = Conditions(sensors=1.0, actuators=True, delay_steps=1, parameters=1.0)


def _scale(name: str, value, high: float) -> float:
    """A feature's scale: a bool (1 or 0) or a number in [0, high]."""
    if isinstance(value, bool):
        return 1.0 if value else 0.0
    return validation.in_range(name, value, 0.0, high)
