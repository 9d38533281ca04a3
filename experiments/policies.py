"""Policy registry: every controller the CLI and campaigns can name, built from an env.

``build_policy(spec, env)`` with ``spec = {"policy": NAME, "params": {...}, ...}``:

==================  ==========================================================  =================
name                controller                                                   params
==================  ==========================================================  =================
zero                no torque (free drift)                                       —
lqr                 ``baselines.lqr.LQRPolicy`` on the nominal linearization     discretization, Q, R
lqr-ft              fault-tolerant LQR: IMM FDI + redesign over the healthy       discretization,
                    wheels (``baselines.fault_tolerant``)                        degraded_effectiveness, fdi
mpc                 model-predictive control on each plant's nominal symbolic    see each module
                    model (``baselines.mpc``, ``mpc_slosh``, ``mpc_magnetorquer``,
                    ``mpc_linear``; needs CasADi: ``pip install
                    'attitude-envs[optimal]'``)
mpc-ft              the gyrostat MPC with the IMM fault detector's actuator      fdi, horizon_steps, ...
                    model (``baselines.mpc_fault_tolerant``)
mpc-constrained     the gyrostat MPC with ConstrainedSlew-v0's keep-out cones,   horizon_steps, ...
                    body-rate and wheel-speed limits as path constraints
                    (``baselines.mpc_constrained``; needs CasADi)
eigenaxis           rate-limited eigenaxis slew (``baselines.cbf``;              rate_fraction, gains
                    ConstrainedSlew-v0; blind to the cones)
eigenaxis+cbf       that slew through a CBF safety-filter QP                     cone_gains, buffer_deg, ...
                    (``baselines.cbf``; needs Clarabel)
quaternion-lqr      quaternion LQR law of the feedback-linearization paper       Q, R, stiffness, saturation
feedback-linearization  that paper's feedback linearization + LQR outer loop      Q, R, output, q4_min, ...
linear-lqr          discrete LQR on a LinearSystem-v0 env's (A, B, Q, R)         —
pid                 Ahangarani Farahani et al.'s PID (AirBearing-v0, also        gains (paper-fixed,
                    ReactionWheel-v0)                                            paper-schedule-rad|deg,
                                                                                 or a tune-pid JSON)
slosh-pd, -lqr,     Navabi & Davoodi's P/PD, LQR, Lyapunov, fuzzy                see baselines/slosh.py
-lyapunov, -fuzzy   (FuelSlosh-v0)
amnftsmc, mnftsmc,  Sadigh et al. 2022's sliding-mode controllers                gain overrides
ftsmc-standin       (Magnetorquer-v0)
bdot                B-dot detumbling (Magnetorquer-v0)                           gain_nms
q-learning-lqr      ``agents.QLearningLQR`` (model-free; learns at build time)   constructor kwargs; ``learn``
sb3                 a saved Stable-Baselines3 model (``model: PATH``); behind    deterministic, shield,
                    the CBF safety filter with ``shield: cbf``; on an            shield_params,
                    estimator's output with ``estimator: mekf`` or ``kf``        estimator,
                    (as ``lqr+mekf``; the env needs sensors)                     estimator_params
lqr+mekf,           the controller acting through its estimator                  the controller's, and
amnftsmc+mekf,      (``baselines.estimated``; the env needs sensors, e.g.        estimator_params
slosh-lqr+kf,       ``conditions: flight``): the MEKF on the gyrostats and the
linear-lqr+kf       magnetorquer, filterpy Kalman filters on FuelSlosh and
                    LinearSystem
==================  ==========================================================  =================

Each policy declares the envs it applies to (:attr:`PolicyEntry.envs`); building one for another env
is a ``ValueError`` that lists the policies that fit. Imports are lazy, so a controller whose
package is not installed only fails when it is used, with a ``ValueError`` that says so.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from experiments.training.hyperparams import import_dotted
from experiments.training.policy import SB3Policy

GYROSTATS = ("ReactionWheel", "AirBearing")

#: the safety filters an ``sb3`` policy can play behind (``params: {shield: NAME, shield_params: {...}}``)
SHIELDS = {"cbf": "baselines.cbf:Shielded"}


@dataclass(frozen=True)
class PolicyEntry:
    """A registered policy: ``target`` the ``"module:attribute"`` of a class or factory called as
    ``cls(env, **params)``, or a mapping env name → such a target (one name, one design per
    plant: ``mpc``); ``envs`` the envs it applies to, by name (the env id without namespace and
    version), None for every env (the mapping's keys for a mapping)."""

    target: str | dict[str, str]
    envs: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if isinstance(self.target, dict) and self.envs is None:
            object.__setattr__(self, "envs", tuple(self.target))

    def target_for(self, env_id: str | None) -> str:
        """The target that builds this policy for ``env_id`` (any env for a single target)."""
        if isinstance(self.target, str):
            return self.target
        return self.target[env_name(env_id)] if env_id is not None else next(iter(self.target.values()))

    @property
    def targets(self) -> tuple[str, ...]:
        """Every target of the entry."""
        return (self.target,) if isinstance(self.target, str) else tuple(dict.fromkeys(self.target.values()))


POLICIES: dict[str, PolicyEntry] = {
    "zero": PolicyEntry("baselines.base:ZeroPolicy"),
    "lqr": PolicyEntry("baselines.lqr:LQRPolicy", GYROSTATS),
    "lqr-ft": PolicyEntry("baselines.fault_tolerant:FaultTolerantLQRPolicy", GYROSTATS),
    "mpc": PolicyEntry(
        {
            "ReactionWheel": "baselines.mpc:MPCPolicy",
            "AirBearing": "baselines.mpc:MPCPolicy",
            "FuelSlosh": "baselines.mpc_slosh:SloshMPCPolicy",
            "Magnetorquer": "baselines.mpc_magnetorquer:MagnetorquerMPCPolicy",
            "LinearSystem": "baselines.mpc_linear:LinearMPCPolicy",
        }
    ),
    "mpc-ft": PolicyEntry("baselines.mpc_fault_tolerant:FaultTolerantMPCPolicy", GYROSTATS),
    "mpc-constrained": PolicyEntry("baselines.mpc_constrained:ConstrainedSlewMPCPolicy", ("ConstrainedSlew",)),
    "eigenaxis": PolicyEntry("baselines.cbf:EigenaxisSlewPolicy", ("ConstrainedSlew",)),
    "eigenaxis+cbf": PolicyEntry("baselines.cbf:CBFSafetyFilterPolicy", ("ConstrainedSlew",)),
    "quaternion-lqr": PolicyEntry("baselines.quaternion_lqr:QuaternionLQRPolicy", GYROSTATS),
    "feedback-linearization": PolicyEntry("baselines.feedback_linearization:FeedbackLinearizationPolicy", GYROSTATS),
    "linear-lqr": PolicyEntry("baselines.linear_lqr:LinearLQRPolicy", ("LinearSystem",)),
    "pid": PolicyEntry("baselines.pid:pid_policy", GYROSTATS),
    "slosh-pd": PolicyEntry("baselines.slosh:SloshPDPolicy", ("FuelSlosh",)),
    "slosh-lqr": PolicyEntry("baselines.slosh:SloshLQRPolicy", ("FuelSlosh",)),
    "slosh-lyapunov": PolicyEntry("baselines.slosh:SloshLyapunovPolicy", ("FuelSlosh",)),
    "slosh-fuzzy": PolicyEntry("baselines.fuzzy_slosh:FuzzySloshPDPolicy", ("FuelSlosh",)),
    "amnftsmc": PolicyEntry("baselines.sliding_mode:AMNFTSMCPolicy", ("Magnetorquer",)),
    "mnftsmc": PolicyEntry("baselines.sliding_mode:MNFTSMCPolicy", ("Magnetorquer",)),
    "ftsmc-standin": PolicyEntry("baselines.sliding_mode:FTSMCStandInPolicy", ("Magnetorquer",)),
    "bdot": PolicyEntry("baselines.bdot:BDotPolicy", ("Magnetorquer",)),
    "q-learning-lqr": PolicyEntry("agents:QLearningLQR", ("LinearSystem", "ReactionWheel")),
    "lqr+mekf": PolicyEntry("baselines.estimated:lqr_mekf", GYROSTATS),
    "amnftsmc+mekf": PolicyEntry("baselines.estimated:amnftsmc_mekf", ("Magnetorquer",)),
    "slosh-lqr+kf": PolicyEntry("baselines.estimated:slosh_lqr_kf", ("FuelSlosh",)),
    "linear-lqr+kf": PolicyEntry("baselines.estimated:linear_lqr_kf", ("LinearSystem",)),
    "sb3": PolicyEntry("experiments.training.training:load_trained"),  # the saved model's own env (checked on load)
}


def env_name(env_id: str) -> str:
    """``attitude_envs/FuelSlosh-v0`` → ``FuelSlosh``."""
    return env_id.rsplit("/", 1)[-1].rsplit("-v", 1)[0]


def policies_for(env_id: str) -> list[str]:
    """The registered policies that apply to ``env_id``."""
    return [p for p, entry in POLICIES.items() if entry.envs is None or env_name(env_id) in entry.envs]


def check_policy_env(name: str, env_id: str) -> None:
    """``ValueError`` naming the policies that fit when policy ``name`` does not apply to ``env_id``."""
    envs = POLICIES[check_policy_name(name)].envs
    if envs is not None and env_name(env_id) not in envs:
        raise ValueError(
            f"policy {name!r} does not apply to {env_id} (it applies to {', '.join(envs)}); "
            f"policies for {env_name(env_id)}: {', '.join(p for p in policies_for(env_id) if p != 'sb3')}"
        )


class PolicyUnavailable(ValueError):
    """The named policy exists in the registry but its code is not installed here."""


def check_policy_name(name: str) -> str:
    if name not in POLICIES:
        raise ValueError(f"unknown policy {name!r}; accepted: {sorted(POLICIES)}")
    return name


def import_target(target: str):
    """The object a registry target ``"module:attribute"`` (:data:`POLICIES`) names, imported;
    :class:`PolicyUnavailable` when its package is not installed here."""
    module, attr = target.split(":")
    try:
        return getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:
        raise PolicyUnavailable(f"policy {target!r} is not available in this install ({exc})") from exc


def build_policy(spec: dict[str, Any], env, name: str | None = None):
    """The Policy (``reset(seed)``, ``act(obs, info)``) described by ``spec`` for ``env``.

    ``spec["policy"]``: a registry name; ``spec["params"]``: its keyword arguments;
    for ``sb3``, ``spec["model"]``: the saved model (``.zip`` or run directory);
    for ``q-learning-lqr``, ``spec["learn"]``: keyword arguments of ``learn``.
    """
    kind = check_policy_name(str(spec.get("policy")))
    if getattr(env, "spec", None) is not None:
        check_policy_env(kind, env.spec.id)
    params = dict(spec.get("params") or {})
    label = name or spec.get("name") or kind
    if kind == "sb3":
        if "model" not in spec:
            raise ValueError("policy 'sb3' needs model: PATH (a saved model .zip or its run directory)")
        predictor = import_target(POLICIES[kind].target_for(None))(spec["model"], env)
        policy = SB3Policy(predictor, deterministic=bool(params.get("deterministic", True)), name=label)
        # a model trained behind wrappers that change the action (baselines.cbf.CBFShield, EigenaxisResidual)
        # or the observation (attitude_envs.wrappers.LastAction) plays behind their twins: the outermost
        # wrapper (the last listed) meets the model's action first
        for path, kwargs in reversed(
            import_target("experiments.training.training:trained_env_wrappers")(spec["model"])
        ):
            wrap_policy = getattr(import_dotted(path), "wrap_policy", None)
            if wrap_policy is not None:
                # a shield at deployment would change the command the wrapper's twin records or filters
                if params.get("shield") is not None:
                    raise ValueError(
                        f"model {spec['model']!r} was trained behind {path} and plays behind it: drop shield"
                    )
                policy = wrap_policy(policy, env, **kwargs)
        shield = params.get("shield")
        if shield is None and params.get("shield_params"):
            raise ValueError("params.shield_params needs params.shield (accepted: " + ", ".join(sorted(SHIELDS)) + ")")
        if shield is not None:  # a shield at deployment only
            if shield not in SHIELDS:
                raise ValueError(f"params.shield must be one of {sorted(SHIELDS)} (or absent), got {shield!r}")
            policy = import_target(SHIELDS[shield])(policy, env, **dict(params.get("shield_params") or {}))
        estimator = params.get("estimator")
        if estimator is not None or params.get("estimator_params"):
            from attitude_envs.estimation.estimators import ESTIMATORS, estimator_for
            from baselines.estimated import Estimated

            if estimator is None:
                raise ValueError(f"params.estimator_params needs params.estimator (accepted: {', '.join(ESTIMATORS)})")
            # the model acts on the estimator's rebuilt observation, as lqr+mekf
            built = estimator_for(env, str(estimator), **dict(params.get("estimator_params") or {}))
            policy = Estimated(policy, built)
        policy.name = label
        return policy
    env_id = env.spec.id if getattr(env, "spec", None) is not None else None
    if env_id is None and not isinstance(POLICIES[kind].target, str):
        env_id = f"attitude_envs/{env.unwrapped.env_name}"
    cls = import_target(POLICIES[kind].target_for(env_id))
    if kind == "q-learning-lqr":
        agent = cls(env, name=label, **params)
        agent.learn(**dict(spec.get("learn") or {}))
        return agent
    try:
        policy = cls(env, **params)
    except TypeError as exc:
        raise ValueError(f"bad parameters for policy {kind!r}: {exc}") from exc
    policy.name = label
    return policy
