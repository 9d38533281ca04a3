"""Hyperparameters in the RL Baselines3 Zoo file format (files move between the two projects).

One YAML file per algorithm (``hyperparams/<algo>.yml``), keyed by gymnasium env id::

    attitude_envs/ReactionWheel-v0:
      n_timesteps: !!float 2e5
      policy: 'MlpPolicy'
      normalize: "{'norm_obs': True, 'norm_reward': False}"   # or true / false
      n_envs: 4
      learning_rate: lin_3e-4                                   # Zoo linear schedule
      policy_kwargs: "dict(net_arch=[64, 64], log_std_init=-1)"
      noise_type: 'normal'                                      # TD3 / DDPG / SAC action noise
      noise_std: 0.1
      backend: sbx                                              # optional: train on SBX (JAX); not a Zoo key

The Zoo evaluates ``policy_kwargs`` and ``normalize`` strings with ``eval``; here they are
parsed without executing code (literals, ``dict(...)`` and ``nn.<Activation>`` only).
Command-line overrides use the Zoo's ``key:value`` syntax (value parsed as YAML).
"""

from __future__ import annotations

import ast
import importlib
import json
import math
import re
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from agents.fused_ppo.config import parse_literal
from attitude_envs import validation
from experiments.training.algorithm import Algorithm, check_algorithm

# Keys the Zoo reads itself (not passed to the algorithm's constructor).
ZOO_KEYS = (
    "n_timesteps",
    "policy",
    "normalize",
    "n_envs",
    "noise_type",
    "noise_std",
    "frame_stack",
    "env_wrapper",
    "callback",
)
# ``backend`` (sb3 | sbx) is this project's addition: rl_zoo3 would pass it to the algorithm's
# constructor (a TypeError there), so remove it from an entry before using the entry with rl_zoo3.
_UNSUPPORTED = ("vec_env_wrapper",)


def hyperparams_path(algo: str | Algorithm) -> Path:
    """The shipped YAML file of ``algo`` (package data)."""
    return _shipped(_name(algo))


def _name(algo: str | Algorithm) -> str:
    """The name of a parsed ``algo``, else the checked name."""
    return algo.name if isinstance(algo, Algorithm) else check_algorithm(algo)


def _shipped(name: str) -> Path:
    return Path(str(resources.files("experiments.training") / "hyperparams" / f"{name}.yml"))


def _torch_module(node: ast.Attribute) -> Any:
    """``nn.<Name>`` as the ``torch.nn`` module class (None for anything else)."""
    if not isinstance(node.value, ast.Name | ast.Attribute):
        return None
    import torch.nn as nn  # optional: the sb3 extra; only policy_kwargs with nn.<Activation> need it

    cls = getattr(nn, node.attr, None)
    return cls if isinstance(cls, type) and issubclass(cls, nn.Module) else None


def parse_python_literal(name: str, text: Any) -> Any:
    """A Zoo string such as ``"dict(net_arch=[64, 64])"`` → its value, without ``eval``
    (:func:`agents.fused_ppo.config.parse_literal` with ``nn.<Activation>`` as the torch class
    and tuples kept)."""
    return parse_literal(
        name, text, _torch_module, tuples=True, accepted="a literal, dict(...) or nn.<Activation> expression"
    )


class YamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader that reads numbers as YAML 1.2 does: ``1e-3`` and ``5E4`` are
    floats (YAML 1.1, PyYAML's default, wants a dot, ``1.0e-3``, and reads ``1e-3`` as a string)."""


YamlLoader.yaml_implicit_resolvers = {k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
YamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def load_yaml(text: str) -> Any:
    """A YAML document (one-line or whole file) read with :class:`YamlLoader`."""
    return yaml.load(text, Loader=YamlLoader)  # noqa: S506 (a SafeLoader subclass)


def parse_overrides(items: list[str] | None) -> dict[str, Any]:
    """Zoo-style ``key:value`` overrides (``learning_rate:1e-3``, ``policy_kwargs:"dict(...)"``)."""
    out: dict[str, Any] = {}
    for item in items or []:
        key, sep, value = str(item).partition(":")
        if not sep or not key:
            raise ValueError(f"hyperparameter override must look like key:value, got {item!r}")
        try:
            parsed = load_yaml(value)
        except yaml.YAMLError as exc:
            raise ValueError(f"hyperparameter override {item!r} has a malformed value: {exc}") from exc
        out[key] = parsed
    return out


def read_yaml(path: str | Path) -> Any:
    """A YAML file's content; ``ValueError`` with the file name on a syntax error or missing file."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"YAML file {str(path)!r} does not exist")
    try:
        return load_yaml(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        problem = str(exc).replace("\n", " ")
        raise ValueError(f"malformed YAML in {str(path)!r}: {problem}") from exc


def load_hyperparams(
    algo: str | Algorithm, env_id: str, path: str | Path | None = None, overrides: dict[str, Any] | None = None
) -> dict[str, Any]:
    """The Zoo entry of ``env_id`` in ``path`` (default: the shipped ``<algo>.yml``), with overrides applied.

    Returns the raw entry (Zoo keys included); :func:`split_hyperparams` turns it into
    constructor arguments.
    """
    name = _name(algo)
    path = _shipped(name) if path is None else Path(path)
    table = read_yaml(path)
    if not isinstance(table, dict):
        raise ValueError(f"hyperparameter file {str(path)!r} must map env ids to settings, got {type(table).__name__}")
    if env_id not in table:
        raise ValueError(f"no hyperparameters for env {env_id!r} in {str(path)!r}; it has {sorted(table)}")
    entry = dict(table[env_id] or {})
    entry.update(overrides or {})
    for key in _UNSUPPORTED:
        if key in entry:
            raise ValueError(
                f"hyperparameter {key!r} is not supported here (accepted Zoo keys: {[k for k in ZOO_KEYS if k not in _UNSUPPORTED]})"
            )
    zoo_objects("env_wrapper", entry.get("env_wrapper"))  # their form, before anything trains
    zoo_objects("callback", entry.get("callback"))
    check_hyperparams(entry)
    return entry


#: the range of each numeric hyperparameter that has one (as :mod:`attitude_envs.validation`
#: writes it: low, high, open low, open high); a schedule ``lin_<x>`` is checked on ``x``
RANGES: dict[str, tuple[float, float, bool, bool]] = {
    "gamma": (0.0, 1.0, True, False),
    "gae_lambda": (0.0, 1.0, False, False),
    "learning_rate": (0.0, math.inf, True, True),
    "clip_range": (0.0, math.inf, True, True),
    "clip_range_vf": (0.0, math.inf, True, True),
    "vf_coef": (0.0, math.inf, False, True),
    "max_grad_norm": (0.0, math.inf, True, True),
    "tau": (0.0, 1.0, True, False),
    "noise_std": (0.0, math.inf, False, True),
}
#: whole-number hyperparameters and their least value
MINIMA = {
    "n_timesteps": 1,
    "n_envs": 1,
    "n_steps": 1,
    "batch_size": 1,
    "n_epochs": 1,
    "buffer_size": 1,
    "learning_starts": 0,
}


def check_hyperparams(entry: dict[str, Any]) -> None:
    """``ValueError`` naming the hyperparameter and its accepted range when a value in
    ``entry`` is outside it (``gamma`` in (0, 1], ``learning_rate`` > 0, ``n_steps`` an
    integer >= 1, …: :data:`RANGES`, :data:`MINIMA`). The one check of a recipe, whether it
    comes from a file, ``--params`` (``train``, ``tune``) or a campaign's ``overrides``:
    :func:`load_hyperparams` calls it. ``ent_coef`` may also be SAC's ``auto``/``auto_<x>``."""
    for key, (low, high, open_low, open_high) in RANGES.items():
        if key not in entry or entry[key] is None and key == "clip_range_vf":
            continue
        value = entry[key]
        if (
            isinstance(value, str)
            and value.startswith("lin_")
            and key in ("learning_rate", "clip_range", "clip_range_vf")
        ):
            try:
                value = float(value[4:])
            except ValueError:
                raise ValueError(
                    f"hyperparameter {key} schedule must look like lin_<number>, got {entry[key]!r}"
                ) from None
        validation.in_range(f"hyperparameter {key}", value, low, high, open_low=open_low, open_high=open_high)
    ent = entry.get("ent_coef")
    if ent is not None and not (isinstance(ent, str) and ent.startswith("auto")):
        validation.in_range("hyperparameter ent_coef", ent, 0.0)
    for key, minimum in MINIMA.items():
        if key in entry:
            validation.integer(f"hyperparameter {key}", entry[key], minimum)


def _schedule(name: str, value: Any) -> Any:
    if isinstance(value, str) and value.startswith("lin_"):
        try:
            start = float(value[4:])
        except ValueError as exc:
            raise ValueError(f"{name} schedule must look like lin_<float>, got {value!r}") from exc
        return lambda progress_remaining: progress_remaining * start
    return value


def zoo_objects(name: str, value: Any) -> list[tuple[str, dict[str, Any]]]:
    """The Zoo's ``env_wrapper`` or ``callback`` entry as ``[(dotted path, keyword arguments)]``:
    ``None``, a path ``"package.module.Class"``, a mapping ``{path: {kwargs}}`` of one path, or a
    list of those (applied in order, innermost first). Only the form is checked here; the path is
    imported where the object is built (:func:`import_dotted`)."""
    if value is None or value == []:
        return []
    items = value if isinstance(value, list) else [value]
    out = []
    for item in items:
        if isinstance(item, str) and "." in item:
            out.append((item, {}))
        elif isinstance(item, dict) and len(item) == 1:
            ((path, kwargs),) = item.items()
            if not (isinstance(path, str) and "." in path and (kwargs is None or isinstance(kwargs, dict))):
                raise ValueError(
                    f"{name} entries map 'package.module.Class' to a dict of keyword arguments, got {item!r}"
                )
            out.append((path, dict(kwargs or {})))
        else:
            raise ValueError(
                f"{name} must be 'package.module.Class', {{'package.module.Class': {{kwargs}}}} or a list of them, got {item!r}"
            )
    return out


def jax_wrappers(entry: dict[str, Any]) -> tuple[tuple[str, str], ...]:
    """The JAX twins of a Zoo entry's ``env_wrapper`` list, for the fused trainer: ``((dotted path
    of the twin, its keyword arguments as sorted JSON), ...)`` in the list's order (hashable: a
    compiled program's cache key). Each Gymnasium wrapper names
    its twin in a ``jax_twin`` attribute (:class:`attitude_envs.wrappers.LastAction`); a
    ``ValueError`` names one that has none."""
    out = []
    for path, kwargs in zoo_objects("env_wrapper", entry.get("env_wrapper")):
        twin = getattr(import_dotted(path), "jax_twin", None)
        if twin is None:
            raise ValueError(
                f"the jax backend (the fused trainer) takes only env_wrapper entries with a JAX twin "
                f"(attitude_envs.wrappers.LastAction, baselines.residual.LQRResidual, "
                f"baselines.residual.SloshLQRResidual); {path} has none: train with backend sb3 or sbx"
            )
        out.append((str(twin), json.dumps(kwargs, sort_keys=True)))
    return tuple(out)


def import_dotted(path: str) -> Any:
    """The object a dotted path ``"package.module.Name"`` names (the Zoo's ``env_wrapper`` and
    ``callback`` syntax); ``ValueError`` naming the path when it does not import."""
    module, _, attr = path.rpartition(".")
    try:
        return getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError, ValueError) as exc:
        raise ValueError(f"{path!r} cannot be imported ({exc})") from exc


def split_hyperparams(entry: dict[str, Any], n_actions: int, algorithm: Algorithm | None = None) -> dict[str, Any]:
    """Zoo entry → ``{"n_timesteps", "n_envs", "normalize" (dict | None), "frame_stack", "policy",
    "env_wrapper", "callback", "kwargs"}``.

    ``kwargs`` go to the algorithm's constructor (schedules, ``policy_kwargs`` and action
    noise built; with ``algorithm``, ``policy_kwargs`` adapted to its backend, whose name the
    entry's ``backend`` key gave it); ``normalize`` holds VecNormalize arguments when
    observation/reward normalization is on; ``frame_stack`` (≥ 1, default 1): how many of the
    latest (normalized) observations the policy sees, as the Zoo's ``VecFrameStack``;
    ``env_wrapper`` and ``callback``: :func:`zoo_objects` of the Zoo's keys (Gymnasium wrappers of
    every training and evaluation env; SB3 callbacks of the run).
    """
    entry = dict(entry)
    n_timesteps = int(float(entry.pop("n_timesteps", 100_000)))
    n_envs = int(entry.pop("n_envs", 1))
    if n_timesteps < 1 or n_envs < 1:
        raise ValueError(f"n_timesteps and n_envs must be >= 1, got {n_timesteps} and {n_envs}")
    policy = entry.pop("policy", "MlpPolicy")
    frame_stack = entry.pop("frame_stack", None)
    if frame_stack is None or frame_stack is False:
        frame_stack = 1
    if isinstance(frame_stack, bool) or not isinstance(frame_stack, int) or frame_stack < 1:
        raise ValueError(f"frame_stack must be an integer >= 1 (observations stacked), got {frame_stack!r}")
    entry.pop("backend", None)  # parsed into ``algorithm``
    env_wrapper = zoo_objects("env_wrapper", entry.pop("env_wrapper", None))
    callback = zoo_objects("callback", entry.pop("callback", None))
    normalize = parse_python_literal("normalize", entry.pop("normalize", False))
    if normalize is True:
        normalize = {"norm_obs": True, "norm_reward": True}
    elif not normalize:
        normalize = None
    elif not isinstance(normalize, dict):
        raise ValueError(f"normalize must be a bool or a dict of VecNormalize arguments, got {normalize!r}")
    noise_type = entry.pop("noise_type", None)
    noise_std = float(entry.pop("noise_std", 0.1))
    if "policy_kwargs" in entry:
        entry["policy_kwargs"] = parse_python_literal("policy_kwargs", entry["policy_kwargs"])
    if algorithm is not None:  # the backend's adaptations depend on the algorithm
        policy_kwargs = algorithm.policy_kwargs(entry.get("policy_kwargs"))
        if policy_kwargs is not None:
            entry["policy_kwargs"] = policy_kwargs
    for key in ("learning_rate", "clip_range", "clip_range_vf"):
        if key in entry:
            entry[key] = _schedule(key, entry[key])
    if noise_type is not None:
        # optional: the sb3 extra (this module is also imported by the core command line)
        from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

        kinds = {"normal": NormalActionNoise, "ornstein-uhlenbeck": OrnsteinUhlenbeckActionNoise}
        if noise_type not in kinds:
            raise ValueError(f"noise_type must be one of {sorted(kinds)}, got {noise_type!r}")
        entry["action_noise"] = kinds[noise_type](np.zeros(n_actions), noise_std * np.ones(n_actions))
    return {
        "n_timesteps": n_timesteps,
        "n_envs": n_envs,
        "normalize": normalize,
        "frame_stack": frame_stack,
        "env_wrapper": env_wrapper,
        "callback": callback,
        "policy": policy,
        "kwargs": entry,
    }
