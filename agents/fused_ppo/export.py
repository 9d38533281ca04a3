"""A trained fused-PPO actor as plain numpy arrays, its file, and a numpy predictor (no jax).

:class:`PolicyArrays` holds the actor MLP (kernels ``(in, out)``, biases), the Gaussian's
log-std, the action box and the frozen observation statistics. :class:`NumpyPPOPolicy` plays
it with Stable-Baselines3's ``predict(obs, state=None, episode_start=None, deterministic=True)
-> (action, None)``: the observation normalized as in training, the action the Gaussian's
mean (or a draw from it with ``deterministic=False``) clipped to the action box, so the
suite's evaluator (``experiments.training.callbacks.evaluate_cost``, campaigns, ``attitude-envs
evaluate``) scores JAX-trained policies on the numba envs unchanged.

The file (``model.zip``, the name the suite's run layout uses) is a zip archive with ``data``
(JSON: format, activation, clip and epsilon of the normalization, the module of the policy
class) and ``arrays.npz``. :meth:`NumpyPPOPolicy.load` reads it.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: the ``format`` field of a fused-PPO model file
FORMAT = "attitude-envs-fused-ppo"
FORMAT_VERSION = 1

_ACTIVATIONS = {
    "tanh": np.tanh,
    "relu": lambda x: np.maximum(x, 0.0),
    "elu": lambda x: np.where(x > 0, x, np.expm1(np.minimum(x, 0.0))),
    "silu": lambda x: x / (1.0 + np.exp(-x)),
    "leaky_relu": lambda x: np.where(x >= 0, x, 0.01 * x),
}


def _gelu(x: np.ndarray) -> np.ndarray:
    from scipy.special import erf

    return 0.5 * x * (1.0 + erf(x / np.sqrt(2.0)))


_ACTIVATIONS["gelu"] = _gelu


@dataclass
class PolicyArrays:
    """A deterministic actor: ``mean = L_k(act(… act(L_1(o))))`` with ``L_i(x) = x @ kernels[i] +
    biases[i]`` on the normalized observation ``o = clip((obs - obs_mean) / sqrt(obs_var +
    epsilon), ±clip_obs)`` (no normalization when ``obs_mean`` is None); ``log_std`` the
    Gaussian's log standard deviation (actions,), or gSDE's (latent, actions) matrix, the
    latent the input of the last layer; actions clipped to ``[action_low, action_high]``."""

    kernels: list[np.ndarray]
    biases: list[np.ndarray]
    activation: str
    log_std: np.ndarray
    action_low: np.ndarray
    action_high: np.ndarray
    obs_mean: np.ndarray | None = None
    obs_var: np.ndarray | None = None
    clip_obs: float = 10.0
    epsilon: float = 1e-8
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.activation not in _ACTIVATIONS:
            raise ValueError(f"activation must be one of {sorted(_ACTIVATIONS)}, got {self.activation!r}")
        if not self.kernels or len(self.kernels) != len(self.biases):
            raise ValueError(f"need as many kernels as biases (>= 1), got {len(self.kernels)} and {len(self.biases)}")
        for i in range(1, len(self.kernels)):
            if self.kernels[i].shape[0] != self.kernels[i - 1].shape[1]:
                raise ValueError(
                    f"kernel {i} takes {self.kernels[i].shape[0]} inputs, layer {i - 1} gives {self.kernels[i - 1].shape[1]}"
                )
        if self.kernels[-1].shape[1] != self.action_low.shape[0]:
            raise ValueError(
                f"the actor gives {self.kernels[-1].shape[1]} actions, the action box has {self.action_low.shape[0]}"
            )
        shapes = ((self.n_actions,), (self.kernels[-1].shape[0], self.n_actions))
        if tuple(self.log_std.shape) not in shapes:
            raise ValueError(f"log_std must have shape {shapes[0]} or, for gSDE, {shapes[1]}; got {self.log_std.shape}")

    @property
    def obs_dim(self) -> int:
        return int(self.kernels[0].shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.kernels[-1].shape[1])


def save_policy(arrays: PolicyArrays, path: str | Path) -> Path:
    """Write ``arrays`` as a model file (module docstring); returns its path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    named = {"log_std": arrays.log_std, "action_low": arrays.action_low, "action_high": arrays.action_high}
    for i, (k, b) in enumerate(zip(arrays.kernels, arrays.biases, strict=True)):
        named[f"kernel_{i}"], named[f"bias_{i}"] = k, b
    if arrays.obs_mean is not None:
        named["obs_mean"], named["obs_var"] = arrays.obs_mean, arrays.obs_var
    buffer = io.BytesIO()
    np.savez(buffer, **{k: np.asarray(v, np.float32) for k, v in named.items()})
    data = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "policy_class": {"__module__": __name__, "__name__": "NumpyPPOPolicy"},
        "activation": arrays.activation,
        "n_layers": len(arrays.kernels),
        "normalize_obs": arrays.obs_mean is not None,
        "clip_obs": float(arrays.clip_obs),
        "epsilon": float(arrays.epsilon),
        "meta": arrays.meta,
    }
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("data", json.dumps(data, indent=2))
        zf.writestr("arrays.npz", buffer.getvalue())
    return path


def load_policy(path: str | Path) -> PolicyArrays:
    """The :class:`PolicyArrays` of a model file; ``ValueError`` for another kind of file."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as zf:
            data = json.loads(zf.read("data").decode("utf-8"))
            npz = np.load(io.BytesIO(zf.read("arrays.npz")))
            arrays = {k: npz[k] for k in npz.files}
    except (OSError, zipfile.BadZipFile, KeyError, ValueError) as exc:
        raise ValueError(f"{str(path)!r} is not a fused-PPO model file ({exc})") from exc
    if data.get("format") != FORMAT:
        raise ValueError(f"{str(path)!r} is not a fused-PPO model file (format {data.get('format')!r})")
    n = int(data["n_layers"])
    norm = bool(data["normalize_obs"])
    return PolicyArrays(
        kernels=[arrays[f"kernel_{i}"] for i in range(n)],
        biases=[arrays[f"bias_{i}"] for i in range(n)],
        activation=data["activation"],
        log_std=arrays["log_std"],
        action_low=arrays["action_low"],
        action_high=arrays["action_high"],
        obs_mean=arrays["obs_mean"] if norm else None,
        obs_var=arrays["obs_var"] if norm else None,
        clip_obs=float(data["clip_obs"]),
        epsilon=float(data["epsilon"]),
        meta=dict(data.get("meta") or {}),
    )


class NumpyPPOPolicy:
    """Plays :class:`PolicyArrays` with SB3's ``predict`` (module docstring), in float32 as the
    trainer computes; ``seed`` seeds the draws of ``deterministic=False``. ``observation_space``
    and ``action_space`` are the Gymnasium boxes it was trained for (the observation box
    unbounded: only its shape is known)."""

    def __init__(self, arrays: PolicyArrays, seed: int | None = None) -> None:
        self.arrays = arrays
        self._rng = np.random.default_rng(seed)
        self._act = _ACTIVATIONS[arrays.activation]

    @classmethod
    def load(cls, path: str | Path, device: str | None = None, seed: int | None = None) -> NumpyPPOPolicy:
        """A predictor from a model file (``device`` accepted for SB3's ``load`` signature; CPU)."""
        return cls(load_policy(path), seed=seed)

    def save(self, path: str | Path) -> Path:
        return save_policy(self.arrays, path)

    @property
    def observation_space(self):
        from gymnasium import spaces

        return spaces.Box(-np.inf, np.inf, (self.arrays.obs_dim,), np.float32)

    @property
    def action_space(self):
        from gymnasium import spaces

        a = self.arrays
        return spaces.Box(a.action_low, a.action_high, a.action_low.shape, np.float32)

    def normalize(self, obs: np.ndarray) -> np.ndarray:
        """The observation as the actor sees it (float32)."""
        a = self.arrays
        obs = np.asarray(obs, np.float32)
        if a.obs_mean is None:
            return obs
        scale = np.sqrt(a.obs_var + np.float32(a.epsilon)).astype(np.float32)
        return np.clip((obs - a.obs_mean) / scale, -a.clip_obs, a.clip_obs).astype(np.float32)

    def mean(self, obs: np.ndarray) -> np.ndarray:
        """The Gaussian's mean (unclipped) for observations ``obs`` (..., obs_dim)."""
        return self._forward(obs)[0]

    def _forward(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(mean, latent)``: the mean and the input of the last layer."""
        x = self.normalize(obs)
        last = len(self.arrays.kernels) - 1
        for i, (k, b) in enumerate(zip(self.arrays.kernels, self.arrays.biases, strict=True)):
            if i == last:
                return (x @ k + b).astype(np.float32), x
            x = self._act((x @ k + b).astype(np.float32)).astype(np.float32)
        raise AssertionError("unreachable: PolicyArrays has at least one layer")

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        """``(action, None)``: the clipped mean (``deterministic``) or a clipped Gaussian draw, for
        one observation ``(obs_dim,)`` or a batch ``(n, obs_dim)``."""
        obs = np.asarray(obs, np.float32)
        if obs.shape[-1] != self.arrays.obs_dim or obs.ndim not in (1, 2):
            raise ValueError(
                f"obs must have shape ({self.arrays.obs_dim},) or (n, {self.arrays.obs_dim}), got {obs.shape}"
            )
        action, latent = self._forward(obs)
        std = np.exp(self.arrays.log_std)
        if not deterministic and std.ndim == 1:
            noise = self._rng.standard_normal(action.shape).astype(np.float32)
            action = action + std * noise
        elif not deterministic:  # gSDE: fresh noise weights at every call (sde_sample_freq 1)
            weights = std * self._rng.standard_normal((*latent.shape[:-1], *std.shape)).astype(np.float32)
            action = action + np.einsum("...i,...ia->...a", latent, weights).astype(np.float32)
        return np.clip(action, self.arrays.action_low, self.arrays.action_high).astype(np.float32), None
