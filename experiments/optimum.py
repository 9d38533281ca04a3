"""The optimal-control yardstick J*: the best cost any controller could reach on an episode.

:func:`solve_episode` builds the env's own discrete optimal-control problem for one episode
(:func:`attitude_envs.symbolic.problem_for`: the exact step, cost and limits of the env) and
solves it by direct multiple shooting (Bock & Plitt 1984) with IPOPT (Wächter & Biegler
2006) through CasADi (Andersson et al. 2019), warm-started with the states and actions of a
baseline's rollout on the same episode. The solver is an **oracle**: it knows the episode's
start state, target, true inertia, disturbance and the full fault schedule in advance (no
feedback controller can), so J* is a lower bound on what a causal controller reaches (up to
IPOPT's local optimality), not a competitor; every output says ``"oracle": true``.

``j_star`` is the cost of replaying the optimal actions open loop through the real env
(the sum of ``info["cost"]``), ``j_nlp`` the NLP's objective; they agree to rounding when the
solve converged. Results are cached on disk (:func:`cache_dir`), keyed by a hash of the env
id, keyword arguments, seed, reset options, solver settings and package versions, so
repeated campaign cells are free.

Under flight conditions (``conditions=`` in ``env_kwargs``) the oracle knows the drawn plant
and gains and acts through the env's delay and actuator dynamics (how each stage enters the
problem: the docstrings of :mod:`attitude_envs.symbolic.gyrostat`, ``.linear``, ``.slosh`` and
``.magnetorquer``); for the wheels' Coulomb friction (the gyrostats', Magnetorquer's) the first
solve's ``tanh`` relaxation is followed by re-solves with the signs fixed
(:func:`_fix_friction_signs`), and J* is the cheapest replay among the passes. The cache key
holds the resolved conditions (:func:`conditions_of`; lab keys are unchanged).

The replay also measures the episode with the env's success metric
(:attr:`OptimumResult.measurements`, :mod:`attitude_envs.evaluation.success`), so a report can
say whether the optimum itself succeeds (it need not: J weighs the whole episode, success
only its end).

Requires CasADi: ``pip install 'attitude-envs[optimal]'``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

import attitude_envs
from attitude_envs import symbolic
from attitude_envs.cache import cache_dir as suite_cache_dir
from attitude_envs.constraints import episode_summary
from attitude_envs.files import atomic_write
from attitude_envs.info import policy_view
from attitude_envs.symbolic import BUILDERS, DiscreteProblem, problem_for
from attitude_envs.symbolic.problem import QUIET, SOLVED
from experiments.jsonable import json_ready
from experiments.policies import build_policy

try:
    import casadi
except ImportError as exc:  # the optional extra
    raise ImportError("the optimal-control yardstick needs CasADi: pip install 'attitude-envs[optimal]'") from exc

#: the baselines that apply to each env (registry name, parameters), compared with J* and
#: used for the warm start; the first is the default warm start (the LQR where one applies)
BASELINES: dict[str, list[tuple[str, dict]]] = {
    "LinearSystem-v0": [("linear-lqr", {})],
    "ReactionWheel-v0": [
        ("lqr", {"discretization": "zoh"}),
        ("lqr", {"discretization": "continuous"}),
        ("quaternion-lqr", {}),
        ("feedback-linearization", {}),
        ("pid", {}),
    ],
    "AirBearing-v0": [("lqr", {"discretization": "zoh"}), ("lqr", {"discretization": "continuous"}), ("pid", {})],
    "FuelSlosh-v0": [("slosh-lqr", {}), ("slosh-pd", {})],
    "Magnetorquer-v0": [("amnftsmc", {})],
    # the CBF-filtered eigenaxis slew: a feasible start around the keep-out cones
    "ConstrainedSlew-v0": [("eigenaxis+cbf", {})],
}


@dataclass
class OptimumResult:
    """One episode's optimum (an oracle's: the fault schedule was known to the solver).

    ``j_star``: cost of the optimal actions replayed through the real env; ``j_nlp``: the
    NLP objective; ``j_warm``: the warm start's cost in the env (``warm_start`` names it);
    ``solve_s``: IPOPT wall time, s; ``total_s``: the whole solve (problem build, warm
    start, NLP construction, IPOPT, replay), s; ``status``: IPOPT's return status; ``terminated``:
    the replay ended before the time limit; ``actions``: (n_steps, n_u) normalized actions;
    ``measurements``: the env's success-metric measurements of the replay
    (:meth:`~attitude_envs.evaluation.success.SuccessMetric.measurements`, e.g.
    ``{"final_error_deg": 3.1}``, deg), None for a cache entry written before they were kept.
    """

    env_id: str
    env_kwargs: dict
    seed: int
    options: dict | None
    j_star: float
    j_nlp: float
    j_warm: float
    warm_start: str
    solve_s: float
    total_s: float
    status: str
    iterations: int
    terminated: bool
    notes: str
    actions: np.ndarray = field(repr=False)
    oracle: bool = True
    cached: bool = False
    measurements: dict[str, float] | None = None

    @property
    def solved(self) -> bool:
        return self.status in SOLVED

    def row(self) -> dict[str, Any]:
        """The JSON row of ``optimum.json`` (everything but the actions)."""
        d = asdict(self)
        d.pop("actions")
        return json_ready(d)


def env_name(env_id: str) -> str:
    """``"ReactionWheel-v0"`` of ``"attitude_envs/ReactionWheel-v0"`` or of itself."""
    return env_id.split("/")[-1]


def full_id(env_id: str) -> str:
    """The registered id (``attitude_envs/`` namespace added when missing)."""
    return env_id if "/" in env_id else f"attitude_envs/{env_id}"


def check_env(env_id: str) -> str:
    """The env name of ``env_id``; ValueError when no symbolic model exists for it."""
    name = env_name(env_id)
    if name not in BUILDERS:
        raise ValueError(f"--env / env_id must be one of {sorted(BUILDERS)} for J*, got {env_id!r}")
    return name


def cache_dir() -> Path:
    """``$ATTITUDE_ENVS_CACHE/optimum`` when that variable is set, else
    ``~/.cache/attitude-envs/optimum`` (``$XDG_CACHE_HOME`` replaces ``~/.cache``)."""
    return suite_cache_dir("optimum")


def conditions_of(env_kwargs: dict | None) -> dict | None:
    """The resolved flight conditions of an env built with ``env_kwargs``
    (:meth:`attitude_envs.conditions.Conditions.as_dict`), or None in the lab."""
    from attitude_envs.conditions import Conditions

    cond = Conditions.from_config((env_kwargs or {}).get("conditions"))
    return None if cond.is_lab else cond.as_dict()


def _array_digest(actions) -> str:
    """SHA-256 of an actions array's float64 values and shape."""
    a = np.ascontiguousarray(np.asarray(actions, dtype=float))
    return hashlib.sha256(repr(a.shape).encode() + a.tobytes()).hexdigest()


def _cache_key(env_id, env_kwargs, seed, options, settings) -> str:
    payload = {
        "env_id": env_name(env_id),
        "env_kwargs": json_ready(env_kwargs),
        "seed": seed,
        "options": json_ready(options),
        "settings": settings,
        "version": attitude_envs.__version__,
        "casadi": casadi.__version__,
    }
    conditions = conditions_of(env_kwargs)
    if conditions is not None:  # flight entries keyed by their resolved conditions; lab keys unchanged
        payload["conditions"] = conditions
    text = json.dumps(payload, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


class Replay(NamedTuple):
    """What :func:`replay_measured` returns: ``J`` (sum of ``info["cost"]``, the env's cost
    units), ``terminated`` (a limit crossed before the time limit) and ``measurements`` (the
    env's success-metric measurements from the reset info and the last info)."""

    J: float
    terminated: bool
    measurements: dict[str, float]


def replay_measured(env, actions: np.ndarray, seed: int | None, options: dict | None) -> Replay:
    """The open-loop ``actions`` through the real env from ``reset(seed=, options=)``: J,
    whether it terminated, and ``env.unwrapped.success_metric.measurements(first, last)``
    (first: the reset's info, last: the last step's; the reset's twice without actions), with
    the constraint outcome (:func:`attitude_envs.constraints.episode_summary`) where the env
    has constraints."""
    _, first = env.reset(seed=seed, options=options)
    last = first
    metric = env.unwrapped.success_metric
    constrained = [first] if "violations" in first else None
    total, terminated = 0.0, False
    for a in actions:
        _, _, terminated, truncated, last = env.step(np.asarray(a, dtype=float))
        total += float(last["cost"])
        if constrained is not None:
            constrained.append(last)
        if terminated or truncated:
            break
    measured = metric.measurements(first, last) | episode_summary(constrained or [])
    return Replay(total, bool(terminated), _floats(measured))


def _floats(measurements: dict[str, Any]) -> dict[str, float]:
    return {k: float(v) for k, v in measurements.items()}


def replay(env, actions: np.ndarray, seed: int | None, options: dict | None) -> tuple[float, bool]:
    """``(J, terminated)`` of :func:`replay_measured` (J = sum of ``info["cost"]``); the
    success-metric measurements are its third item."""
    r = replay_measured(env, actions, seed, options)
    return r.J, r.terminated


def policy_rollout(env, policy, seed: int | None, options: dict | None = None, max_steps: int | None = None):
    """``(actions, J)`` of ``policy`` on the episode, to its end or ``max_steps``: the actions
    played, ``(steps, n_u)``; with ``max_steps``, ``(max_steps, n_u)``, zero after an early end.
    The policy sees :func:`policy_view` of each info (no ground truth)."""
    obs, info = env.reset(seed=seed, options=options)
    policy.reset(seed)
    actions, total = [], 0.0
    while max_steps is None or len(actions) < max_steps:
        a = np.asarray(policy.act(obs, policy_view(info)), dtype=float)
        actions.append(a)
        obs, _, terminated, truncated, info = env.step(a)
        total += float(info["cost"])
        if terminated or truncated:
            break
    out = np.zeros((len(actions) if max_steps is None else max_steps, env.action_space.shape[0]))
    out[: len(actions)] = np.reshape(actions, (len(actions), out.shape[1]))
    return out, total


def baseline_rollout(env, spec: tuple[str, dict], seed: int | None, options: dict | None, n_steps: int):
    """``(actions (n_steps, n_u), J)`` of the baseline ``spec`` (registry name, parameters) on
    the episode (:func:`policy_rollout`). Steps after an early end are zero actions."""
    name, params = spec
    return policy_rollout(env, build_policy({"policy": name, "params": dict(params)}, env), seed, options, n_steps)


def _warm_start(env, problem: DiscreteProblem, warm_start, seed, options) -> tuple[np.ndarray, float, str]:
    """Warm-start actions, their J in the env and a label."""
    name = env_name(problem.env_id)
    if warm_start is None:
        actions = np.zeros((problem.n_steps, problem.n_u))
        return actions, replay(env, actions, seed, options)[0], "zero"
    if not isinstance(warm_start, str):
        actions = np.asarray(warm_start, dtype=float)
        if actions.shape != (problem.n_steps, problem.n_u):
            raise ValueError(
                f"warm_start actions must have shape {(problem.n_steps, problem.n_u)}, got {actions.shape}"
            )
        return actions, replay(env, actions, seed, options)[0], "actions"
    specs = BASELINES.get(name, [])
    if warm_start == "lqr":
        chosen = specs[:1]
    elif warm_start == "best":
        chosen = specs
    else:
        raise ValueError(f"warm_start must be None, 'lqr', 'best' or an actions array, got {warm_start!r}")
    if not chosen:
        raise ValueError(f"warm_start {warm_start!r}: no baseline applies to {name}; pass None or an actions array")
    best = None
    for spec in chosen:
        actions, total = baseline_rollout(env, spec, seed, options, problem.n_steps)
        label = spec[0] + "".join(f":{k}:{v}" for k, v in spec[1].items())
        if best is None or total < best[1]:
            best = (actions, total, label)
    return best


def solve_problem(
    problem: DiscreteProblem,
    actions0: np.ndarray,
    max_iter: int = 1000,
    tol: float = 1e-10,
    ipopt_options: dict | None = None,
    jit: bool = False,
    scale_states: bool = True,
    fixed_steps: int = 0,
) -> tuple[np.ndarray, float, str, int, float]:
    """Multiple shooting + IPOPT from the warm start ``actions0`` (states from its rollout
    through ``problem.step``). ``jit``: compile the step and its derivatives with the system's
    C compiler (CasADi's ``"shell"`` compiler; a few seconds up front, faster iterations on
    long horizons). ``scale_states``: scale each state by its largest warm-start magnitude (at
    least 1) for IPOPT. ``fixed_steps``: the first ``fixed_steps`` actions are held at
    ``actions0``'s (clipped to the bounds) and only the rest is optimized — the optimum *after*
    a given prefix, e.g. a causal controller's actions until a fault's onset.
    Returns ``(actions, objective, status, iterations, solve_s)``."""
    n, nx, nu = problem.n_steps, problem.n_x, problem.n_u
    if isinstance(fixed_steps, bool) or not isinstance(fixed_steps, (int, np.integer)) or not 0 <= fixed_steps <= n:
        raise ValueError(f"fixed_steps must be an integer in [0, {n}] (the episode's steps), got {fixed_steps!r}")
    fixed_steps = int(fixed_steps)
    states0, _ = problem.rollout(actions0)
    step = problem.step
    if jit:
        ins = step.sx_in()
        # the compiler's sources and objects go to a temporary directory, never the working one
        build_dir = tempfile.mkdtemp(prefix="attitude-envs-jit-")
        jit_opts = {
            "jit": True,
            "compiler": "shell",
            "jit_options": {"flags": ["-O0"], "directory": build_dir},
            "jit_cleanup": True,
        }
        step = casadi.Function("step_jit", ins, step.call(ins), step.name_in(), step.name_out(), jit_opts)
    # states scaled by their warm-start magnitude (e.g. wheel speeds of hundreds of rad/s next
    # to unit quaternions), defects likewise: IPOPT sees O(1) variables and constraints
    scale = np.maximum(np.max(np.abs(states0), axis=0), 1.0) if scale_states else np.ones(nx)
    xs_scaled = casadi.MX.sym("X", nx, n)  # x_1 … x_N / scale (x_0 is fixed)
    xs = casadi.diag(casadi.DM(scale)) @ xs_scaled
    us = casadi.MX.sym("A", nu, n)
    previous = casadi.horzcat(casadi.DM(problem.x0), xs[:, : n - 1])
    x_next, costs = step.map(n)(previous, us, casadi.DM(problem.step_inputs()))
    constraints = [casadi.vec(casadi.diag(casadi.DM(1.0 / scale)) @ x_next - xs_scaled)]
    lbg, ubg = [np.zeros(nx * n)], [np.zeros(nx * n)]
    if problem.g is not None:
        if problem.g.n_in() == 2:  # g(x_k, p_k): the step's per-step input of x_k's own step (none for x_N)
            inputs = problem.step_inputs()
            after = np.hstack([inputs[:, 1:], np.zeros((inputs.shape[0], 1))])
            path = casadi.vec(problem.g.map(n)(xs, casadi.DM(after)))
        else:
            path = casadi.vec(problem.g.map(n)(xs))
        constraints.append(path)
        lbg.append(np.full(path.shape[0], -np.inf))
        ubg.append(np.zeros(path.shape[0]))
    w = casadi.vertcat(casadi.vec(xs_scaled), casadi.vec(us))
    nlp = {"x": w, "f": casadi.sum2(costs), "g": casadi.vertcat(*constraints)}
    opts = {
        **QUIET,
        "expand": False,  # the mapped step keeps the graph small: a fast build, one derivative per step
        "ipopt.max_iter": int(max_iter),
        "ipopt.tol": float(tol),
        "ipopt.bound_relax_factor": 0.0,  # actions stay in [a_lb, a_ub] exactly (the env clips)
        "ipopt.mu_strategy": "adaptive",
        **(ipopt_options or {}),
    }
    solver = casadi.nlpsol("optimum", "ipopt", nlp, opts)
    clipped = np.clip(actions0, problem.a_lb, problem.a_ub)
    a_lb = np.tile(problem.a_lb, (n, 1))
    a_ub = np.tile(problem.a_ub, (n, 1))
    a_lb[:fixed_steps] = a_ub[:fixed_steps] = clipped[:fixed_steps]
    lbx = np.concatenate([np.full(nx * n, -np.inf), a_lb.ravel()])
    ubx = np.concatenate([np.full(nx * n, np.inf), a_ub.ravel()])
    w0 = np.concatenate([(states0[1:] / scale).ravel(), clipped.ravel()])
    start = time.perf_counter()
    sol = solver(x0=w0, lbx=lbx, ubx=ubx, lbg=np.concatenate(lbg), ubg=np.concatenate(ubg))
    solve_s = time.perf_counter() - start
    stats = solver.stats()
    w_opt = np.asarray(sol["x"]).ravel()
    actions = w_opt[nx * n :].reshape(n, nu)
    return actions, float(sol["f"]), str(stats.get("return_status")), int(stats.get("iter_count", -1)), solve_s


#: re-solves with the signs fixed, at most (each from the last one's trajectory)
FRICTION_SIGN_PASSES = 3


def _fix_friction_signs(env, problem, actions, seed, options, max_iter, tol, jit):
    """Flight conditions' wheel friction: the first solve smooths the Coulomb term's
    ``sign(Ω)`` as ``tanh(Ω/ε)`` (:data:`attitude_envs.symbolic.actuators.FRICTION_EPS_RAD_S`);
    this re-solves with ``sign(Ω_k)`` of the last trajectory fixed per step (then the problem
    is the env's wherever the optimum keeps those signs) until the signs repeat, at most
    :data:`FRICTION_SIGN_PASSES` times, on every plant whose symbolic model fixes them
    (:data:`attitude_envs.symbolic.FRICTION_SIGN_MODULES`: the gyrostats' wheels,
    Magnetorquer's wheel with its −Ω convention).

    Each pass holds the speeds a margin from zero on the side of their signs
    (:func:`attitude_envs.symbolic.with_friction_signs`) at every step, unless that is
    certainly infeasible — a state the commands cannot move (the first ``delay_steps``
    states: the delay line delivers zeros) inside the margin, e.g. wheels at rest at the
    start — or IPOPT fails on it; then only at the steps where the last trajectory already
    clears the margin; and if that fails too, with the signs alone. Later passes keep the
    level that solved. ``(passes, solve_s)``: each pass's ``(problem, actions, j_nlp, status,
    iterations)`` (none when the episode has no Coulomb friction: the lab) and their IPOPT
    time; the caller keeps the pass whose env replay is cheapest."""
    if not symbolic.has_coulomb_friction(env):
        return [], 0.0  # the lab, and flight without the actuator dynamics: nothing relaxed
    from attitude_envs.symbolic.actuators import ChainSpec

    passes, solve_total = [], 0.0
    speeds = symbolic.friction_speeds(env, problem.rollout(actions)[0][:-1])
    signs = np.sign(speeds)
    delay = ChainSpec.from_env(env.unwrapped, 0).delay_steps
    margin = symbolic.friction_sign_margin(env)
    # x_1 … x_d do not depend on the commands (the delay line delivers zeros): a speed inside
    # the margin there makes the margin at every step infeasible
    fixed_start = np.abs(speeds[1 : 1 + delay]) * (signs[1 : 1 + delay] != 0)
    level = 1 if np.any((fixed_start > 0) & (fixed_start < margin)) else 0  # 0: everywhere, 1: where clear, 2: none
    for _ in range(FRICTION_SIGN_PASSES):
        while level <= 2:
            env.reset(seed=seed, options=options)
            where = (True, np.abs(speeds) >= margin, False)[level]
            fixed = symbolic.with_friction_signs(env, signs, where)
            if fixed is None:
                return passes, solve_total
            a, j, status, it, s = solve_problem(fixed, actions, max_iter, tol, jit=jit)
            solve_total += s
            if status in SOLVED:
                break
            level += 1
        if status not in SOLVED:
            break
        actions = np.clip(a, fixed.a_lb, fixed.a_ub)
        passes.append((fixed, actions, j, status, it))
        speeds = symbolic.friction_speeds(env, fixed.rollout(actions)[0][:-1])
        new = np.sign(speeds)
        if np.array_equal(new, signs):
            break
        signs = new
    return passes, solve_total


def solve_episode(
    env_id: str,
    env_kwargs: dict | None = None,
    seed: int = 0,
    options: dict | None = None,
    warm_start: str | np.ndarray | None = "lqr",
    max_iter: int = 1000,
    tol: float = 1e-10,
    cache: bool = True,
    jit: bool = False,
) -> OptimumResult:
    """J* of one episode (``reset(seed=seed, options=options)`` of ``env_id`` built with
    ``env_kwargs``): an **oracle** optimum, the fault schedule and every episode draw known.

    ``warm_start``: ``"lqr"`` (default: the first of :data:`BASELINES` for the env, the LQR
    where one applies, rolled out on the same episode), ``"best"`` (the cheapest of the
    env's baselines), None (zero actions) or an (n_steps, n_u) actions array; states and
    actions are initialized from that rollout. ``max_iter``, ``tol``: IPOPT's. ``cache``:
    read and write the on-disk cache (:func:`cache_dir`; an array warm start by its content).
    ``jit``: compile the step (see :func:`solve_problem`; the result is the same).
    Raises ValueError for an env, fault or disturbance without a symbolic model."""
    check_env(env_id)
    env_kwargs = dict(env_kwargs or {})
    named = warm_start is None or isinstance(warm_start, str)
    # an actions array is keyed by its content: the same warm start finds the same entry
    warm_key = warm_start if named else {"actions_sha256": _array_digest(warm_start)}
    settings = {"warm_start": warm_key, "max_iter": int(max_iter), "tol": float(tol)}
    path = cache_dir() / f"{_cache_key(env_id, env_kwargs, seed, options, settings)}.json" if cache else None
    if path is not None and path.is_file():
        found = _read_cache(path)
        if found is not None:
            return found
        # else an unreadable or outdated entry: solve again and overwrite it
    start = time.perf_counter()
    env = gym.make(full_id(env_id), **env_kwargs)
    try:
        problem = problem_for(env, seed=seed, options=options)
        actions0, j_warm, label = _warm_start(env, problem, warm_start, seed, options)
        actions, j_nlp, status, iterations, solve_s = solve_problem(problem, actions0, max_iter, tol, jit=jit)
        actions = np.clip(actions, problem.a_lb, problem.a_ub)
        passes, extra_s = _fix_friction_signs(env, problem, actions, seed, options, max_iter, tol, jit)
        solve_s += extra_s
        j_star, terminated, measurements = replay_measured(env, actions, seed, options)
        for p_fixed, a_fixed, j_fixed, status_fixed, it_fixed in passes:
            # every pass's commands are the env's to play: J* is the best replay among them
            replayed = replay_measured(env, a_fixed, seed, options)
            if status_fixed in SOLVED and replayed.J < j_star:
                problem, actions, j_nlp, status, iterations = p_fixed, a_fixed, j_fixed, status_fixed, it_fixed
                j_star, terminated, measurements = replayed
    finally:
        env.close()
    result = OptimumResult(
        env_id=env_name(env_id),
        env_kwargs=env_kwargs,
        seed=seed,
        options=options,
        j_star=j_star,
        j_nlp=j_nlp,
        j_warm=j_warm,
        warm_start=label,
        solve_s=solve_s,
        total_s=time.perf_counter() - start,
        status=status,
        iterations=iterations,
        terminated=terminated,
        notes=problem.notes,
        actions=actions,
        measurements=measurements,
    )
    if path is not None:
        _write_cache(path, result)
    return result


def _write_cache(path: Path, result: OptimumResult) -> None:
    """``result`` (actions included) to the cache file ``path``, atomically."""
    data = {**result.row(), "actions": np.asarray(result.actions).tolist()}
    data.pop("cached")
    atomic_write(path, json.dumps(data))


def _read_cache(path: Path) -> OptimumResult | None:
    """The cached result in ``path`` (``cached=True``), None when unreadable or outdated. An
    entry written before measurements were kept gets them by replaying its actions
    (:func:`with_measurements`) and is rewritten with them; where the replay no longer gives
    its J* (the env changed), its measurements stay None."""
    try:
        data = json.loads(path.read_text())
        data["actions"] = np.asarray(data["actions"], dtype=float)
        result = OptimumResult(**{**data, "cached": True})
    except (ValueError, TypeError, KeyError):
        return None
    if result.measurements is None:
        try:
            result = with_measurements(result)
        except ValueError:
            return result
        _write_cache(path, result)
    return result


def with_measurements(result: OptimumResult, rtol: float = 1e-9) -> OptimumResult:
    """``result`` with :attr:`~OptimumResult.measurements` and ``terminated`` of replaying its
    actions through the env (:func:`replay_measured`; one episode, no solve). ValueError when
    the replay's J differs from ``result.j_star`` by more than ``rtol`` (relative): the env or
    the actions are not the ones J* was computed with, so the measurements would not be J*'s."""
    env = gym.make(full_id(result.env_id), **dict(result.env_kwargs))
    try:
        j, terminated, measurements = replay_measured(env, result.actions, result.seed, result.options)
    finally:
        env.close()
    if not abs(j - result.j_star) <= rtol * max(abs(result.j_star), 1e-300):
        raise ValueError(
            f"replaying the J* actions of {result.env_id} seed {result.seed} gives J = {j!r}, not "
            f"j_star = {result.j_star!r} (relative difference above {rtol:g}): measurements not taken"
        )
    return dataclasses.replace(result, terminated=terminated, measurements=measurements)


def cached_result(
    env_id: str,
    env_kwargs: dict | None = None,
    seed: int = 0,
    options: dict | None = None,
    warm_start: str | None = "lqr",
    max_iter: int = 1000,
    tol: float = 1e-10,
) -> OptimumResult | None:
    """The on-disk cache's result of :func:`solve_episode` with these arguments, or None when
    it was never solved (nothing is solved here)."""
    settings = {"warm_start": warm_start, "max_iter": int(max_iter), "tol": float(tol)}
    path = cache_dir() / f"{_cache_key(env_id, dict(env_kwargs or {}), seed, options, settings)}.json"
    return _read_cache(path) if path.is_file() else None


def solve_episodes(
    env_id: str,
    env_kwargs: dict | None,
    seeds: Sequence[int],
    progress: Callable[[str], None] | None = None,
    **kwargs: Any,
) -> list[OptimumResult]:
    """:func:`solve_episode` for each seed, with a progress line per seed."""
    results = []
    for i, seed in enumerate(seeds):
        r = solve_episode(env_id, env_kwargs, seed, **kwargs)
        results.append(r)
        if progress is not None:
            ratio = r.j_star / r.j_warm if r.j_warm else float("nan")
            progress(
                f"[{i + 1}/{len(seeds)}] seed {seed}: J* = {r.j_star:.6g} (J*/J[{r.warm_start}] = {ratio:.4f}), "
                f"{r.status}, {r.iterations} it, {r.solve_s:.1f} s{' (cached)' if r.cached else ''}"
            )
    return results


def markdown_table(results: Sequence[OptimumResult]) -> str:
    """A short markdown table of the results (one row per seed)."""
    lines = [
        "J* is an oracle optimum (the solver knows the fault schedule and every episode draw).",
        "",
        "| env | seed | J* | J_nlp | warm start | J warm | J*/J warm | status | solve s |",
        "|---|---:|---:|---:|---|---:|---:|---|---:|",
    ]
    for r in results:
        ratio = r.j_star / r.j_warm if r.j_warm else float("nan")
        lines.append(
            f"| {r.env_id} | {r.seed} | {r.j_star:.6g} | {r.j_nlp:.6g} | {r.warm_start} | {r.j_warm:.6g} | "
            f"{ratio:.4f} | {r.status} | {r.solve_s:.1f} |"
        )
    return "\n".join(lines) + "\n"


def write_results(out: str | Path, results: Sequence[OptimumResult]) -> Path:
    """``out/optimum.json`` (one row per seed, ``"oracle": true``) and ``out/optimum.md``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "optimum.json"
    path.write_text(json.dumps([r.row() for r in results], indent=2) + "\n")
    (out / "optimum.md").write_text(markdown_table(results))
    return path
