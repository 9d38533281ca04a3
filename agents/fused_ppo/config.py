"""The fused trainer's settings from an RL Baselines3 Zoo PPO entry, checked (numpy only: no jax).

A Zoo entry (``experiments/training/hyperparams/ppo.yml``) splits in two here:

* :class:`PPOConfig`: what fixes the compiled program's shapes and branches (env count, rollout
  length, minibatch size, epochs, layer widths, activation, which schedules and normalizations
  are on). It is hashable and static under ``jax.jit``: another value compiles another program.
* :class:`Hparams`: the floating-point hyperparameters (learning rate, γ, GAE λ, clip range,
  coefficients, initial log-std, schedule horizon). It is a ``NamedTuple``, hence a JAX pytree:
  the trainer takes it as a traced argument, so ``jax.vmap`` over a stack of them trains many
  settings in one compiled program (:func:`stack_hparams`).

The keys mean what they mean to Stable-Baselines3's ``PPO`` (2.x) with the Zoo's
``normalize`` (``VecNormalize``) and ``policy_kwargs`` (``MlpPolicy``; ``use_sde`` is SB3's
gSDE with its defaults: full std, ``exp``, features not learned); a key the trainer does not
implement (``frame_stack`` > 1, ``squash_output``, an optimizer class …) or a value out of
range raises a ``ValueError`` naming it. ``env_wrapper`` is not the program's: the caller wraps
the JAX plant in the listed wrappers' twins (``experiments.training.hyperparams.jax_wrappers``).
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

#: activations by the names a Zoo entry may give them (torch class names, flax function names)
ACTIVATIONS = {
    "tanh": "tanh",
    "relu": "relu",
    "elu": "elu",
    "gelu": "gelu",
    "silu": "silu",
    "leakyrelu": "leaky_relu",
    "leaky_relu": "leaky_relu",
}
#: Zoo keys (read by the Zoo itself, not PPO's constructor) this trainer accepts
ZOO_KEYS = ("n_timesteps", "policy", "normalize", "n_envs", "frame_stack", "backend", "env_wrapper")
#: Stable-Baselines3 PPO constructor keys this trainer accepts
PPO_KEYS = (
    "learning_rate",
    "n_steps",
    "batch_size",
    "n_epochs",
    "gamma",
    "gae_lambda",
    "clip_range",
    "clip_range_vf",
    "normalize_advantage",
    "ent_coef",
    "vf_coef",
    "max_grad_norm",
    "use_sde",
    "sde_sample_freq",
    "target_kl",
    "stats_window_size",
    "policy_kwargs",
)
#: ``policy_kwargs`` keys this trainer accepts (``squash_output`` only False)
POLICY_KEYS = ("net_arch", "activation_fn", "ortho_init", "log_std_init", "squash_output", "share_features_extractor")
#: ``normalize`` keys (VecNormalize arguments; its γ is PPO's, as ``train`` passes it)
NORMALIZE_KEYS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "epsilon")


class Hparams(NamedTuple):
    """The traced hyperparameters (floats, or arrays of floats stacked along a leading axis).

    ``learning_rate`` and ``clip_range`` (and ``clip_range_vf``) are the schedules' initial
    values: a linear schedule (:attr:`PPOConfig.lr_schedule`) decays them to 0 at
    ``schedule_timesteps`` env steps, evaluated as SB3 does after each rollout on the
    progress ``1 - steps / schedule_timesteps``. ``gamma`` also discounts the return that
    reward normalization scales by. ``target_kl`` is used only when
    :attr:`PPOConfig.use_target_kl`; ``clip_range_vf`` only when :attr:`PPOConfig.clip_vf_schedule`
    is set. ``log_std_init`` is the Gaussian's initial log standard deviation (action units, log)."""

    learning_rate: Any = 3e-4
    gamma: Any = 0.99
    gae_lambda: Any = 0.95
    clip_range: Any = 0.2
    clip_range_vf: Any = 0.0
    ent_coef: Any = 0.0
    vf_coef: Any = 0.5
    max_grad_norm: Any = 0.5
    log_std_init: Any = 0.0
    target_kl: Any = 0.0
    schedule_timesteps: Any = 1_000_000.0


@dataclass(frozen=True)
class PPOConfig:
    """The static settings of a fused PPO program (see the module docstring).

    ``n_steps`` decisions per env per rollout over ``n_envs`` envs; minibatches of
    ``batch_size`` transitions (a last, smaller one when it does not divide the rollout, as
    SB3 does), ``n_epochs`` passes; ``pi_arch`` / ``vf_arch`` the hidden widths of the actor and
    the critic (``()``: linear); ``total_timesteps`` the budget of the one-call ``train``
    (rounded up to whole rollouts). ``use_sde``: gSDE exploration (Raffin, Kober & Stulp 2022),
    its noise weights drawn at each rollout's start and, when ``sde_sample_freq`` > 0, every
    ``sde_sample_freq`` steps of it (SB3's ``collect_rollouts``)."""

    n_envs: int = 1
    n_steps: int = 2048
    batch_size: int = 64
    n_epochs: int = 10
    pi_arch: tuple[int, ...] = (64, 64)
    vf_arch: tuple[int, ...] = (64, 64)
    activation: str = "tanh"
    ortho_init: bool = True
    lr_schedule: str = "constant"
    clip_schedule: str = "constant"
    clip_vf_schedule: str | None = None
    normalize_advantage: bool = True
    use_target_kl: bool = False
    norm_obs: bool = False
    norm_reward: bool = False
    clip_obs: float = 10.0
    clip_reward: float = 10.0
    norm_epsilon: float = 1e-8
    use_sde: bool = False
    sde_sample_freq: int = -1
    total_timesteps: int = 1_000_000

    @property
    def rollout_size(self) -> int:
        """Env steps per rollout (all envs)."""
        return self.n_envs * self.n_steps

    @property
    def num_updates(self) -> int:
        """Rollouts (PPO updates) of the one-call ``train``."""
        return -(-self.total_timesteps // self.rollout_size)

    def __post_init__(self) -> None:
        for name in ("n_envs", "n_steps", "n_epochs", "total_timesteps"):
            _integer(name, getattr(self, name), 1)
        _integer("batch_size", self.batch_size, 2 if self.normalize_advantage else 1)
        if self.normalize_advantage and self.rollout_size < 2:
            raise ValueError(
                f"n_steps * n_envs must be > 1 to normalize advantages, got {self.n_steps} * {self.n_envs}"
            )
        for name in ("pi_arch", "vf_arch"):
            arch = getattr(self, name)
            if not isinstance(arch, tuple) or not all(isinstance(w, int) and w >= 1 for w in arch):
                raise ValueError(f"{name} must be a tuple of layer widths >= 1, got {arch!r}")
        if self.activation not in set(ACTIVATIONS.values()):
            raise ValueError(f"activation must be one of {sorted(set(ACTIVATIONS.values()))}, got {self.activation!r}")
        for name in ("lr_schedule", "clip_schedule"):
            if getattr(self, name) not in ("constant", "linear"):
                raise ValueError(f"{name} must be 'constant' or 'linear', got {getattr(self, name)!r}")
        if self.clip_vf_schedule not in (None, "constant", "linear"):
            raise ValueError(f"clip_vf_schedule must be None, 'constant' or 'linear', got {self.clip_vf_schedule!r}")
        for name in ("clip_obs", "clip_reward", "norm_epsilon"):
            _positive(name, getattr(self, name))
        if not isinstance(self.use_sde, bool):
            raise ValueError(f"use_sde must be true or false, got {self.use_sde!r}")
        _integer("sde_sample_freq", self.sde_sample_freq, -1)


def _integer(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or int(value) < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def _float(name: str, value: Any) -> float:
    if isinstance(value, bool):
        raise ValueError(f"{name} must be a number, got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(out):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return out


def _positive(name: str, value: Any) -> float:
    out = _float(name, value)
    if out <= 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return out


def _in_range(name: str, value: Any, low: float, high: float, low_open: bool = False) -> float:
    out = _float(name, value)
    if out > high or out < low or (low_open and out == low):
        bracket = "(" if low_open else "["
        raise ValueError(f"{name} must be in {bracket}{low}, {high}], got {value!r}")
    return out


def _schedule(name: str, value: Any) -> tuple[str, float]:
    """``("linear", start)`` for a Zoo ``lin_<start>``, else ``("constant", value)``; start > 0."""
    if isinstance(value, str) and value.startswith("lin_"):
        try:
            start = float(value[4:])
        except ValueError as exc:
            raise ValueError(f"{name} schedule must look like lin_<float>, got {value!r}") from exc
        return "linear", _positive(name, start)
    if callable(value):
        raise ValueError(f"{name} must be a number or a Zoo schedule 'lin_<float>', got the callable {value!r}")
    return "constant", _positive(name, value)


def _literal(node: ast.AST, attribute: Callable[[ast.Attribute], Any], tuples: bool) -> Any:
    def value(n: ast.AST) -> Any:
        if isinstance(n, ast.Constant):
            return n.value
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.USub):
            return -value(n.operand)
        if isinstance(n, ast.List | ast.Tuple):
            items = [value(e) for e in n.elts]
            return tuple(items) if tuples and isinstance(n, ast.Tuple) else items
        if isinstance(n, ast.Dict):
            return {value(k): value(v) for k, v in zip(n.keys, n.values, strict=True)}
        if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "dict" and not n.args:
            return {kw.arg: value(kw.value) for kw in n.keywords}
        if isinstance(n, ast.Attribute):
            found = attribute(n)
            if found is not None:
                return found
        raise ValueError(f"unsupported expression {ast.unparse(n)!r}")

    return value(node)


def parse_literal(
    name: str,
    value: Any,
    attribute: Callable[[ast.Attribute], Any] | None = None,
    tuples: bool = False,
    accepted: str = "a literal or dict(...) expression",
) -> Any:
    """A Zoo string such as ``"dict(net_arch=[64], activation_fn=nn.Tanh)"`` → its value,
    without ``eval``: literals, lists (tuples as lists unless ``tuples``), dicts, ``dict(...)``
    and attributes, each ``nn.<Name>`` given by ``attribute(node)`` (default: its name, ``"Tanh"``;
    None: not accepted). A ``ValueError`` naming ``name`` and what is ``accepted``."""
    if not isinstance(value, str):
        return value
    resolve = attribute or (lambda node: node.attr)
    try:
        return _literal(ast.parse(value, mode="eval").body, resolve, tuples)
    except (SyntaxError, ValueError) as exc:
        raise ValueError(f"{name} must be {accepted}, got {value!r} ({exc})") from exc


def activation_name(value: Any) -> str:
    """The trainer's name of an activation given as ``nn.Tanh`` (a class or its name) or ``"tanh"``."""
    raw = getattr(value, "__name__", value)
    key = str(raw).rsplit(".", 1)[-1].lower()
    if key not in ACTIVATIONS:
        raise ValueError(f"policy_kwargs.activation_fn must be one of {sorted(ACTIVATIONS)}, got {value!r}")
    return ACTIVATIONS[key]


def _arch(value: Any) -> tuple[tuple[int, ...], tuple[int, ...]]:
    def widths(where: str, v: Any) -> tuple[int, ...]:
        if not isinstance(v, list | tuple):
            raise ValueError(f"{where} must be a list of layer widths, got {v!r}")
        return tuple(_integer(f"{where}[{i}]", w, 1) for i, w in enumerate(v))

    if isinstance(value, dict):
        unknown = sorted(set(value) - {"pi", "vf"})
        if unknown:
            raise ValueError(f"policy_kwargs.net_arch accepts the keys ['pi', 'vf'], got {unknown}")
        return widths("net_arch.pi", value.get("pi", [])), widths("net_arch.vf", value.get("vf", []))
    arch = widths("net_arch", value)
    return arch, arch


def _unknown(where: str, mapping: dict[str, Any], accepted: tuple[str, ...]) -> None:
    unknown = sorted(set(mapping) - set(accepted))
    if unknown:
        raise ValueError(f"fused PPO: {where} {unknown} not supported (accepted: {list(accepted)})")


def from_zoo(
    entry: dict[str, Any], total_timesteps: int | None = None, wrapped: bool = False
) -> tuple[PPOConfig, Hparams]:
    """``(PPOConfig, Hparams)`` of a Zoo PPO entry (the raw entry: strings such as ``lin_3e-4`` and
    ``"dict(...)"`` as in the YAML file, or their parsed values). ``total_timesteps`` (env
    steps) overrides the entry's ``n_timesteps`` as the budget and the schedules' horizon.
    An entry with ``env_wrapper`` needs ``wrapped``: the caller has wrapped the JAX plant in
    the wrappers' twins (``experiments.training.jax_training.wrapped_plant``).
    ``ValueError`` naming the key for an unknown or unsupported key or an out-of-range value."""
    if not isinstance(entry, dict):
        raise ValueError(f"a Zoo entry must be a mapping, got {type(entry).__name__}")
    _unknown("hyperparameters", entry, ZOO_KEYS + PPO_KEYS)
    if entry.get("env_wrapper") and not wrapped:
        raise ValueError(
            "fused PPO: env_wrapper is applied by the caller (experiments.training.jax_training.wrapped_plant); "
            "wrap the JAX plant in the wrappers' twins and pass wrapped=True"
        )
    e = dict(entry)
    policy = e.get("policy", "MlpPolicy")
    if policy != "MlpPolicy":
        raise ValueError(f"fused PPO: policy must be 'MlpPolicy', got {policy!r}")
    backend = str(e.get("backend", "jax")).lower()
    if backend not in ("jax", "sb3", "sbx"):  # the same entry may serve the other backends
        raise ValueError(f"backend must be one of ['jax', 'sb3', 'sbx'], got {e.get('backend')!r}")
    frame_stack = e.get("frame_stack")
    if frame_stack not in (None, False, 1):
        raise ValueError(f"fused PPO: frame_stack {frame_stack!r} is not supported (1 only)")
    use_sde = e.get("use_sde", False)
    if not isinstance(use_sde, bool):
        raise ValueError(f"use_sde must be true or false, got {use_sde!r}")
    n_timesteps = total_timesteps if total_timesteps is not None else e.get("n_timesteps", 1_000_000)
    total = _integer("n_timesteps", int(_float("n_timesteps", n_timesteps)), 1)

    normalize = parse_literal("normalize", e.get("normalize", False))
    if normalize is True:
        normalize = {"norm_obs": True, "norm_reward": True}
    elif not normalize:
        normalize = {"norm_obs": False, "norm_reward": False}
    elif not isinstance(normalize, dict):
        raise ValueError(f"normalize must be a bool or a dict of VecNormalize arguments, got {normalize!r}")
    _unknown("normalize keys", normalize, NORMALIZE_KEYS)

    pk = parse_literal("policy_kwargs", e.get("policy_kwargs")) or {}
    if not isinstance(pk, dict):
        raise ValueError(f"policy_kwargs must be a dict, got {pk!r}")
    _unknown("policy_kwargs keys", pk, POLICY_KEYS)
    if pk.get("squash_output"):
        raise ValueError(
            "fused PPO: policy_kwargs.squash_output is not supported (actions are clipped, as SB3's default)"
        )
    pi_arch, vf_arch = _arch(pk.get("net_arch", {"pi": [64, 64], "vf": [64, 64]}))

    lr_kind, lr = _schedule("learning_rate", e.get("learning_rate", 3e-4))
    clip_kind, clip = _schedule("clip_range", e.get("clip_range", 0.2))
    clip_vf_kind, clip_vf = None, 0.0
    if e.get("clip_range_vf") is not None:
        clip_vf_kind, clip_vf = _schedule("clip_range_vf", e["clip_range_vf"])
    target_kl = e.get("target_kl")
    for name in ("normalize_advantage", "ortho_init"):
        value = (pk if name == "ortho_init" else e).get(name, True)
        if not isinstance(value, bool):
            raise ValueError(f"{name} must be true or false, got {value!r}")
    config = PPOConfig(
        n_envs=_integer("n_envs", e.get("n_envs", 1), 1),
        n_steps=_integer("n_steps", e.get("n_steps", 2048), 1),
        batch_size=_integer("batch_size", e.get("batch_size", 64), 2 if e.get("normalize_advantage", True) else 1),
        n_epochs=_integer("n_epochs", e.get("n_epochs", 10), 1),
        pi_arch=pi_arch,
        vf_arch=vf_arch,
        activation=activation_name(pk.get("activation_fn", "tanh")),
        ortho_init=bool(pk.get("ortho_init", True)),
        lr_schedule=lr_kind,
        clip_schedule=clip_kind,
        clip_vf_schedule=clip_vf_kind,
        normalize_advantage=bool(e.get("normalize_advantage", True)),
        use_target_kl=target_kl is not None,
        norm_obs=bool(normalize.get("norm_obs", True)),
        norm_reward=bool(normalize.get("norm_reward", True)),
        clip_obs=_positive("normalize.clip_obs", normalize.get("clip_obs", 10.0)),
        clip_reward=_positive("normalize.clip_reward", normalize.get("clip_reward", 10.0)),
        norm_epsilon=_positive("normalize.epsilon", normalize.get("epsilon", 1e-8)),
        use_sde=use_sde,
        sde_sample_freq=_integer("sde_sample_freq", e.get("sde_sample_freq", -1), -1),
        total_timesteps=total,
    )
    hparams = Hparams(
        learning_rate=lr,
        gamma=_in_range("gamma", e.get("gamma", 0.99), 0.0, 1.0, low_open=True),
        gae_lambda=_in_range("gae_lambda", e.get("gae_lambda", 0.95), 0.0, 1.0),
        clip_range=clip,
        clip_range_vf=clip_vf,
        ent_coef=_float("ent_coef", e.get("ent_coef", 0.0)),
        vf_coef=_in_range("vf_coef", e.get("vf_coef", 0.5), 0.0, math.inf),
        max_grad_norm=_positive("max_grad_norm", e.get("max_grad_norm", 0.5)),
        log_std_init=_float("policy_kwargs.log_std_init", pk.get("log_std_init", 0.0)),
        target_kl=_positive("target_kl", target_kl) if target_kl is not None else 0.0,
        schedule_timesteps=float(total),
    )
    return config, hparams


def stack_hparams(settings: list[Hparams]) -> Hparams:
    """Many :class:`Hparams` as one whose fields are float32 arrays along a leading axis (for
    ``jax.vmap(train, in_axes=(None, 0))``)."""
    if not settings:
        raise ValueError("stack_hparams needs at least one setting")
    return Hparams(*(np.asarray(v, dtype=np.float32) for v in zip(*settings, strict=True)))


def as_float32(hparams: Hparams) -> Hparams:
    """``hparams`` with float32 array fields (one setting, or a stack)."""
    return Hparams(*(np.asarray(v, dtype=np.float32) for v in hparams))
