"""Fault-tolerant LQR: IMM fault detection and isolation, then an LQR redesigned for the
actuators that are left (active fault-tolerant control by reconfiguration).

The policy runs the plain LQR (:class:`~baselines.lqr.LQRPolicy`) while the IMM bank of
:class:`~attitude_envs.estimation.fdi.ActuatorFDI` sees no fault. It feeds the FDI only what a
flight computer has: the commanded motor torques (``info["commanded"]``), the measured rate and
wheel speeds (``info["measured"]``) and the time; on an air bearing also the nominal
centre-of-mass offset torque at the measured attitude (mean of the step's two ends). When the
FDI isolates wheel ``i`` at effectiveness ``e_i`` (0: an outage) the policy

1. records ``E = diag(e)`` and restarts the FDI with that fault known (so a second wheel can
   be isolated after the first);
2. redesigns the LQR for the body torques the remaining wheels can deliver: with ``U`` an
   orthonormal basis of ``range(A E)`` (``A`` the nominal wheel axes) the input is
   ``v`` with body torque ``T = U v``; the nominal linearization's controllable subspace for
   that input (Kalman decomposition; with two wheels left one body axis is lost) gets the
   discrete LQR gain of its exact ZOH discretization, the env's ``Q`` and the cost's ``R``
   on the delivered torque;
3. allocates ``T`` over the healthy wheels by the pseudo-inverse of the effective wheel
   matrix, ``u = −(A E)⁺ T`` (wheel action frame), or, in the body action frame (where the env
   allocates the demand over all wheels, ``u = −A⁺ T_cmd``), commands the demand
   ``T_cmd = M⁺ T`` with ``M = −A E (−A⁺)`` the body torque delivered per unit demand.

This is active fault-tolerant control by FDI + controller redesign (Zhang & Jiang 2008,
bibliographical review of reconfigurable fault-tolerant control systems) with the
minimum-norm wheel allocation of :mod:`baselines.allocation` (the feedback-linearization
paper, eqs. 9–12) restricted to the healthy wheels. Works on ReactionWheel-v0
(``action_frame`` ``"wheel"`` or ``"body"``) and AirBearing-v0; one env at a time (not a
batch). On ReactionWheel-v0's ``two-wheel-failure`` scenario it is only slightly better than
the plain LQR: the lost axis needs nonlinear control.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from attitude_envs.estimation.fdi import ActuatorFDI, measurements
from attitude_envs.linearization import LinearModel
from attitude_envs.plants.gyrostat import gravity_torque_nm
from baselines.allocation import wheel_model
from baselines.lqr import LQRPolicy

_RANK_TOL = 1e-9


def _orth(m: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the column space of ``m`` (relative rank tolerance 1e-9)."""
    u, s, _ = np.linalg.svd(m, full_matrices=False)
    if s.size == 0 or s[0] == 0.0:
        return np.zeros((m.shape[0], 0))
    return u[:, s > _RANK_TOL * s[0]]


def controllable_subspace(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Orthonormal basis (n × r) of the controllable subspace of ``(A, B)``:
    the range of ``[B, AB, …, Aⁿ⁻¹B]``."""
    blocks, block = [], b
    for _ in range(a.shape[0]):
        blocks.append(block)
        block = a @ block
    return _orth(np.hstack(blocks))


class FaultTolerantLQRPolicy:
    """LQR + IMM FDI + reconfiguration over the healthy wheels (see the module docstring).

    Parameters: ``discretization`` (``"zoh"`` or ``"continuous"``, as for
    :class:`~baselines.lqr.LQRPolicy`), ``degraded_effectiveness`` (the FDI's fault levels,
    default ``(0.0, 0.5)``: outage and half effectiveness), ``fdi`` (further
    :class:`~attitude_envs.estimation.fdi.ActuatorFDI` keywords), ``name``.

    After each step :attr:`isolated` lists the isolations so far as dicts
    ``{"index", "time_s", "effectiveness", "probability"}`` and :attr:`effectiveness` the
    assumed actuator effectiveness (1 healthy).
    """

    def __init__(
        self,
        env,
        discretization: str = "zoh",
        degraded_effectiveness: float | Sequence[float] = (0.0, 0.5),
        fdi: dict[str, Any] | None = None,
        name: str | None = None,
    ) -> None:
        base = env.unwrapped
        model = wheel_model(env)
        self.name = name or "lqr-ft"
        self._lqr = LQRPolicy(env, discretization)
        self._discretization = discretization
        self._model = model
        self._frame = getattr(base, "action_frame", "wheel")
        self._fdi_kwargs = {"degraded_effectiveness": degraded_effectiveness, **dict(fdi or {})}
        ActuatorFDI.for_env(env, **self._fdi_kwargs)  # checks the FDI keywords now
        self._env = env
        p = model.params
        self._axes = p.wheel_axes
        self._max_torque = p.max_wheel_torque_nm
        self._n_x = model.n_state
        self._lin_wheel = model.linearize(input="wheel")
        self._offset = bool(np.any(p.offset_torque_nm != 0.0))
        self._last_offset_nm: np.ndarray | None = None
        self._fdi: ActuatorFDI | None = None
        self.effectiveness = np.ones(p.n_wheels)
        self.isolated: list[dict[str, Any]] = []
        self._gain: np.ndarray | None = None  # v = −K x after a reconfiguration
        self._to_action: np.ndarray | None = None  # normalized action = to_action @ v

    def reset(self, seed: int | None = None) -> None:
        self._fdi = None
        self._last_offset_nm = None
        self.effectiveness = np.ones(self._axes.shape[1])
        self.isolated = []
        self._gain = self._to_action = None

    def act(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """Normalized action for one observation (not a batch); reads ``info["measured"]``,
        ``info["commanded"]`` and ``info["time_s"]``, never the truth."""
        self._monitor(info)
        if self._gain is None:
            return self._lqr.act(obs, info)
        x = np.asarray(obs, dtype=float)[: self._n_x]
        return np.clip(self._to_action @ (-self._gain @ x), -1.0, 1.0).astype(np.float32)

    # ------------------------------------------------------------------ FDI
    def _new_fdi(self, info: dict[str, Any]) -> ActuatorFDI | None:
        if np.all(self.effectiveness < 1.0):
            return None  # every wheel isolated: nothing left to monitor
        fdi = ActuatorFDI.for_env(self._env, known_effectiveness=self.effectiveness, **self._fdi_kwargs)
        fdi.reset(*measurements(info))
        return fdi

    def _offset_torque_nm(self, info: dict[str, Any]) -> np.ndarray | None:
        """The nominal offset torque over the step that just ended (N·m, body axes): the mean
        of its values at the measured attitudes of the step's start and end; None without one."""
        if not self._offset:
            return None
        q = np.asarray(info["measured"]["attitude"], dtype=float)
        now = gravity_torque_nm(self._model.params, q) if np.all(np.isfinite(q)) else self._last_offset_nm
        before = now if self._last_offset_nm is None else self._last_offset_nm
        self._last_offset_nm = now
        return None if now is None else 0.5 * (before + now)

    def _monitor(self, info: dict[str, Any]) -> None:
        external = self._offset_torque_nm(info)
        if self._fdi is None and not self.isolated:  # first call of the episode: the reset's info
            self._fdi = self._new_fdi(info)
            return
        if self._fdi is None:
            return
        self._fdi.update(info["commanded"], *measurements(info), info["time_s"], external)
        det = self._fdi.detection
        if det is None:
            return
        self.isolated.append(dict(det))
        self.effectiveness[det["index"]] = det["effectiveness"]
        self._redesign()
        self._fdi = self._new_fdi(info)

    # ------------------------------------------------------------------ redesign
    def _redesign(self) -> None:
        """LQR gain and allocation for the wheels' assumed effectiveness :attr:`effectiveness`."""
        model, lin = self._model, self._lin_wheel
        eff = np.diag(self.effectiveness)
        a_eff = self._axes @ eff  # body torque −A E u from commanded motor torques u
        u_basis = _orth(a_eff)  # 3 × r: the body torques the wheels can still deliver
        if self._frame == "body":
            alloc = model.allocation  # the env's u = −A⁺ T_cmd
            delivered = -a_eff @ alloc  # body torque per unit demand
            to_cmd = alloc @ np.linalg.pinv(delivered) @ u_basis  # v -> commanded motor torques
            to_action = np.linalg.pinv(delivered) @ u_basis / self._max_torque
        else:
            to_cmd = -np.linalg.pinv(a_eff) @ u_basis
            to_action = to_cmd / self._max_torque
        b_v = lin.B @ eff @ to_cmd  # the delivered wheel torques drive the plant
        if model.cost_input == "body":
            r_v = u_basis.T @ model.cost.R @ u_basis
        else:
            g = eff @ to_cmd
            r_v = g.T @ model.cost.R @ g
        basis = controllable_subspace(lin.A, b_v)
        if basis.shape[1] == 0:  # no wheel left: command nothing
            self._gain, self._to_action = np.zeros((b_v.shape[1], self._n_x)), to_action
            return
        reduced = LinearModel(basis.T @ lin.A @ basis, basis.T @ b_v, basis.T @ lin.Q @ basis, r_v)
        if self._discretization == "zoh":
            reduced = reduced.discretize(model.control_dt_s)
        self._gain = reduced.lqr_gain() @ basis.T
        self._to_action = to_action
