"""The agent's data supply: its seeded random generator, the batches it collects (or is
given), the number of env samples used so far, and the input-signal guard every batch
passes before it is learned from.
"""

from __future__ import annotations

import warnings

import numpy as np

from agents.qlqr.data import EnvAdapter, Transitions, collect
from agents.qlqr.estimators import InsufficientExcitationError, lstsq_tall


class Sampler:
    """Collects batches of transitions under a behaviour gain (:func:`agents.qlqr.data.collect`).

    ``rng`` (from ``seed``) draws the probing input, the sampled start states and, on the
    first batch, the env's reset seed. ``given`` (a :class:`~agents.qlqr.data.Transitions`)
    replaces the next batch once; ``data`` is the last batch, ``samples_used`` the number of
    transitions used so far and ``input_signal`` the last batch's probe-to-state ratio
    (:meth:`check_input_signal`).
    """

    def __init__(
        self,
        adapter: EnvAdapter,
        exploration_std: np.ndarray,
        state_std: np.ndarray,
        mode: str,
        input_signal_limit: float,
        n_unknowns: int,
        seed: int | None,
    ) -> None:
        self.adapter = adapter
        self.exploration_std = exploration_std
        self.state_std = state_std
        self.mode = mode
        self.input_signal_limit = input_signal_limit
        self.n_unknowns = n_unknowns
        self.rng = np.random.default_rng(seed)
        self.samples_used = 0
        self.data: Transitions | None = None
        self.given: Transitions | None = None
        self.input_signal: float | None = None

    def collect(self, n_samples: int, gain: np.ndarray) -> Transitions:
        """The next batch: ``given`` if set, else ``n_samples`` fresh transitions under
        ``u = −gain·x + η``; counted, kept as ``data`` and checked (:meth:`check_input_signal`)."""
        if self.given is not None:
            data, self.given = self.given, None
        else:
            env_seed = None if self.samples_used else int(self.rng.integers(2**31 - 1))
            data = collect(
                self.adapter,
                n_samples,
                gain,
                self.exploration_std,
                self.sample_std(gain),
                self.rng,
                env_seed,
                self.mode,
            )
        self.samples_used += len(data)
        self.data = data  # kept even when the guard below refuses it, for inspection
        self.input_signal = self.check_input_signal(data)
        return data

    def sample_std(self, gain: np.ndarray) -> np.ndarray:
        """Spread of the sampled start states for a behaviour gain: ``state_std``, shrunk so
        that the feedback part ``−gain·x`` of the action stays within half the actuator range
        (RMS), since saturated inputs carry no excitation (one-step samples of a linear
        plant are equally informative at any scale; a nonlinear one is more linear there)."""
        M = np.eye(self.adapter.m) if self.adapter.input_map is None else self.adapter.input_map
        rms = np.sqrt(((M @ gain) ** 2) @ (self.state_std**2))
        limit = 0.5 * self.adapter.action_scale
        with np.errstate(divide="ignore"):
            shrink = float(np.min(np.where(rms > 0, limit / rms, np.inf)))
        return self.state_std * min(1.0, shrink)

    def check_input_signal(self, data: Transitions) -> float:
        """Excitation guard that feature scaling cannot hide (a probe too small
        relative to the state). Per sample, the next-state change the probe of each input
        causes, ``‖b̂_j‖·|u_kj|`` (``B̂`` from a row-normalized least-squares fit
        ``x⁺ ≈ Âx + B̂u``, a diagnostic only), relative to ``‖x⁺_k‖``; the p-th largest over the
        samples (p equations must carry the input's effect), minimized over the inputs. Below
        ``input_signal_limit`` the input's effect is lost in floating-point round-off."""
        n = self.adapter.n
        Z = np.hstack([data.X, data.U])
        s = np.sqrt(np.mean(Z**2, axis=0))
        s[s == 0] = 1.0
        row = np.linalg.norm(Z / s, axis=1)
        row[row == 0] = 1.0
        coef = lstsq_tall(Z / s / row[:, None], data.Xn / row[:, None]) / s[:, None]
        b_norm = np.linalg.norm(coef[n:], axis=1)  # ‖b̂_j‖ per input
        size = np.linalg.norm(data.Xn, axis=1)
        size[size == 0] = np.finfo(float).tiny
        per_sample = np.abs(data.U) * b_norm / size[:, None]
        k = min(self.n_unknowns, len(per_sample))
        ratio = float(np.min(np.sort(per_sample, axis=0)[-k]))
        if not ratio >= self.input_signal_limit:
            raise InsufficientExcitationError(
                f"the probing input changes the next state by only {ratio:.2g} of its size (< input_signal_limit "
                f"{self.input_signal_limit:.2g}): its effect is lost in round-off; raise exploration_std"
            )
        if ratio < 1e-6:
            warnings.warn(
                f"the probing input changes the next state by only {ratio:.2g} of its size: expect "
                "round-off-limited accuracy; raise exploration_std",
                stacklevel=5,  # the first batch's: QLearningLQR.learn
            )
        return ratio
