"""Scenario presets (YAML files shipped in this package) and their loader.

A scenario is a YAML mapping::

    name: wheel-failure
    description: ...
    env: attitude_envs/ReactionWheel-v0     # null: the user names the env
    env_kwargs: {preset: pyramid-4wheel, sensors: {...}}
    faults: [ {kind: outage, target: actuator, index: 0, onset_s: 10.0}, ... ]
    campaign: {kinds: [...], severities: [...], onsets_s: [...], index: 0, seeds: [...]}  # optional

``faults`` use the dict format of :mod:`attitude_envs.faults` / :mod:`attitude_envs.sensors`
and are passed to the env at construction (``faults=``), so every episode has them.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import gymnasium as gym
import yaml

from attitude_envs import validation

_KEYS = {"name", "description", "env", "env_kwargs", "faults", "campaign"}


def list_scenarios() -> list[str]:
    """Names of the scenario presets shipped with the package."""
    files = resources.files(__package__).iterdir()
    return sorted(f.name[: -len(".yaml")] for f in files if f.name.endswith(".yaml"))


def load_scenario(name: str) -> dict:
    """A scenario preset by name, or a YAML file by path; checks its keys."""
    path = Path(name)
    if path.suffix in {".yaml", ".yml"} and path.is_file():
        text = path.read_text()
    else:
        names = list_scenarios()
        if name not in names:
            raise ValueError(f"scenario must be one of {names} or a path to a .yaml file, got {name!r}")
        text = resources.files(__package__).joinpath(f"{name}.yaml").read_text()
    data = yaml.safe_load(text)
    if not isinstance(data, dict):
        raise ValueError(f"scenario {name!r} must be a YAML mapping")
    validation.known_keys(f"scenario {name!r}", data, _KEYS)
    data.setdefault("env", None)
    data["env_kwargs"] = dict(data.get("env_kwargs") or {})
    data["faults"] = list(data.get("faults") or [])
    return data


def make_scenario_env(scenario: dict | str, env_id: str | None = None, **overrides) -> gym.Env:
    """``gym.make`` the scenario's env with its kwargs and faults (``env_id`` and keyword
    ``overrides`` take precedence). Faults are validated by the env: bad ones raise."""
    sc = load_scenario(scenario) if isinstance(scenario, str) else scenario
    env_id = env_id or sc.get("env")
    if env_id is None:
        raise ValueError(f"scenario {sc.get('name')!r} names no env: pass env_id (e.g. --env attitude_envs/...)")
    kwargs = dict(sc["env_kwargs"])
    if sc["faults"]:
        kwargs["faults"] = sc["faults"]
    kwargs.update(overrides)
    return gym.make(env_id, **kwargs)
