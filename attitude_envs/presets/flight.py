"""The flight conditions of each plant (:mod:`attitude_envs.conditions`), every value cited.

A :class:`FlightTable` holds, per env:

* ``sensors``: the sensor layer's channel parameters (:mod:`attitude_envs.sensors`; units
  of each channel, per sample at ``period_s``);
* ``actuators``: the actuator model (:mod:`attitude_envs.actuator_dynamics`). ``lag_s`` is
  in seconds and ``duty`` a fraction; ``resolution``, ``coulomb`` and ``rate_limit`` are
  fractions of each actuator's limit (``rate_limit`` per second), ``viscous`` a fraction
  of the limit per rad/s of wheel speed, so one table serves every preset of a plant. A
  number applies to every actuator, a tuple gives one per actuator;
* ``delay_steps``: the computation delay, in control periods;
* ``gain_tolerance``: each actuator's scale-factor error, drawn per episode uniformly
  within ± this fraction (a number, or one per actuator);
* ``plant``: the plant's own parameter tolerances, read by its env.

Each value is a :class:`~attitude_envs.presets.Sourced`: a datasheet, a paper or a
standard, or ``"assumed: <reason>"``. ``python -m attitude_envs.presets.flight`` prints
them.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from attitude_envs.actuator_dynamics import ActuatorModel
from attitude_envs.presets import Sourced

ARCSEC = math.pi / (180.0 * 3600.0)
DEG_PER_HOUR = math.pi / (180.0 * 3600.0)  # rad/s


@dataclass(frozen=True)
class FlightTable:
    """The cited flight values of one plant (see the module docstring)."""

    env: str
    sensors: Mapping[str, Mapping[str, Sourced]]
    actuators: Mapping[str, Sourced]
    delay_steps: Sourced
    gain_tolerance: Sourced
    plant: Mapping[str, Sourced] = field(default_factory=lambda: MappingProxyType({}))

    def sensor_config(self, noise_scale: float = 1.0) -> dict:
        """The ``sensors=`` dict of these conditions; ``noise_scale`` multiplies the white
        noise, the bias walk and the initial bias spread (not the sample periods)."""
        out = {}
        for channel, entries in self.sensors.items():
            p = {k: _number_or_axes(v.value) for k, v in entries.items()}
            for key in ("noise_std", "bias_walk_std", "initial_bias_std"):
                if key in p:
                    p[key] = p[key] * noise_scale
            out[channel] = p
        return out

    def actuator_model(self, limits: np.ndarray) -> ActuatorModel:
        """The actuator model for actuators of these ``limits`` (own units)."""
        lim = np.asarray(limits, dtype=float)
        entries = {}
        for key, sourced in self.actuators.items():
            v = np.broadcast_to(np.asarray(sourced.value, dtype=float), lim.shape)
            entries[key] = v * lim if key in ("resolution", "coulomb", "rate_limit", "viscous") else v
        return ActuatorModel.build(lim, **entries)

    def gain_tolerance_of(self, n_actuators: int) -> np.ndarray:
        """The scale-factor tolerance of each of ``n_actuators`` actuators."""
        return np.broadcast_to(np.asarray(self.gain_tolerance.value, dtype=float), (n_actuators,)).copy()

    def plant_value(self, key: str) -> float:
        """A plant tolerance (KeyError naming the table when it has none)."""
        if key not in self.plant:
            raise KeyError(f"the flight table of {self.env} has no plant tolerance {key!r}")
        return float(self.plant[key].value)

    def sources(self) -> list[tuple[str, object, str]]:
        """Every ``(name, value, source)`` of the table, for docs and the printout."""
        rows = [(f"sensors.{c}.{k}", v.value, v.source) for c, e in self.sensors.items() for k, v in e.items()]
        rows += [(f"actuators.{k}", v.value, v.source) for k, v in self.actuators.items()]
        rows += [("delay_steps", self.delay_steps.value, self.delay_steps.source)]
        rows += [("gain_tolerance", self.gain_tolerance.value, self.gain_tolerance.source)]
        rows += [(f"plant.{k}", v.value, v.source) for k, v in self.plant.items()]
        return rows


def _number_or_axes(value) -> float | np.ndarray:
    """A table value as the sensor layer takes it: a float, or one float per axis."""
    arr = np.asarray(value, dtype=float)
    return float(arr) if arr.ndim == 0 else arr.copy()


def _frozen(mapping: dict) -> MappingProxyType:
    return MappingProxyType({k: _frozen(v) if isinstance(v, dict) else v for k, v in mapping.items()})


_TABLES: dict[str, FlightTable] = {}


def register(family: str, table: FlightTable) -> FlightTable:
    """Make ``table`` the flight conditions of every env id ``<family>-v*``."""
    _TABLES[family] = table
    return table


def table(env_name: str, preset: str | None = None) -> FlightTable:
    """The flight table of env ``env_name`` (``"ReactionWheel-v0"`` or
    ``"attitude_envs/ReactionWheel-v1"``; the family before ``-v`` names it; ``preset`` is for tables that differ by preset, none today)."""
    _load_tables()
    family = env_name.rpartition("/")[2].split("-v")[0]
    if family not in _TABLES:
        raise ValueError(f"{env_name} has no flight conditions yet (known: {sorted(_TABLES)})")
    return _TABLES[family]


def make_table(
    env: str,
    *,
    sensors: dict,
    actuators: dict,
    delay_steps: Sourced,
    gain_tolerance: Sourced,
    plant: dict | None = None,
) -> FlightTable:
    """A :class:`FlightTable` with read-only mappings."""
    return FlightTable(env, _frozen(sensors), _frozen(actuators), delay_steps, gain_tolerance, _frozen(plant or {}))


#: the modules that register the plants' tables (imported on first use)
TABLE_MODULES = ("flight_gyrostat", "flight_magnetorquer", "flight_slosh", "flight_linear")


def all_tables() -> dict[str, FlightTable]:
    """Every plant's flight table by family name (``"ReactionWheel"``, …)."""
    _load_tables()
    return dict(_TABLES)


def _load_tables() -> None:
    for name in TABLE_MODULES:
        importlib.import_module(f"attitude_envs.presets.{name}")


def main() -> None:  # pragma: no cover - a printout
    # the registry of the imported module (run as a script this file is a second module)
    from attitude_envs.presets import flight as registry

    for family, t in sorted(registry.all_tables().items()):
        print(f"## {family}")
        for name, value, source in t.sources():
            print(f"- {name} = {value}: {source}")


if __name__ == "__main__":  # pragma: no cover
    main()
