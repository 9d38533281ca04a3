"""The env-stepping section: env steps/s of the JAX plants (``jax.vmap`` over N envs in a jitted
``lax.scan``) against the numba batched env at the same N, alternating rounds."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from benchmarks.env_speed import _with_spread
from benchmarks.jax_training.speed import jax_device
from benchmarks.jax_training.task import CAMPAIGNS, campaign_task

STEPPING_ENV_IDS = ("attitude_envs/AirBearing-v1", "attitude_envs/ReactionWheel-v1")
GPU_STEPPING = ("attitude_envs/ReactionWheel-v1", 65_536)


def scan_stepper(env, params, n: int, steps: int):
    """``run(key, state, action) -> (key, state, rewards)``: ``steps`` decisions of ``n`` envs
    (``jax.vmap`` of the plant's autoresetting ``step``) in one ``lax.scan``, the same action
    (one row per env) every decision."""
    import jax
    import jax.numpy as jnp

    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    def run(key, state, action):
        def body(carry, _):
            k, st = carry
            k, sub = jax.random.split(k)
            _, st, reward, _, _, _ = step(jax.random.split(sub, n), st, action, params)
            return (k, st), jnp.sum(reward)

        (key, state), rewards = jax.lax.scan(body, (key, state), None, length=steps)
        return key, state, rewards

    return run


def env_stepping(
    env_ids: tuple[str, ...], sizes: tuple[int, ...], seconds: float, rounds: int, steps_per_call: int, pinned: str
) -> list[dict[str, Any]]:
    """Env steps/s of the JAX plants (``jax.vmap`` over N envs, ``lax.scan`` of ``steps_per_call``
    decisions per jitted call) vs the numba batched env at the same N, alternating rounds."""
    import gymnasium as gym
    import jax
    import jax.numpy as jnp

    from attitude_envs.jax import make
    from benchmarks.env_speed import _time_vector
    from experiments.machine_reference import seconds_per_call

    gpu = jax.devices()[0].platform == "gpu"
    cases = []
    for env_id in env_ids:
        kwargs = campaign_task(env_id).env_kwargs if env_id in CAMPAIGNS else {}
        env, params = make(env_id, **kwargs)
        ns = list(sizes) + ([GPU_STEPPING[1]] if gpu and env_id == GPU_STEPPING[0] else [])
        for n in ns:
            numba = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
            space = numba.single_action_space
            actions = np.random.default_rng(0).uniform(space.low, space.high, (n, *space.shape)).astype(np.float32)
            actions *= 0.5

            key = jax.random.PRNGKey(0)
            _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key, n), params)
            action = jnp.asarray(actions)
            start = time.perf_counter()
            run = scan_stepper(env, params, n, steps_per_call)
            compiled = jax.jit(run).lower(key, state, action).compile()
            compile_s = time.perf_counter() - start
            carry = {"key": key, "state": state}

            def call(compiled=compiled, carry=carry, action=action) -> None:
                carry["key"], carry["state"], rewards = compiled(carry["key"], carry["state"], action)
                jax.block_until_ready(rewards)

            call()
            cases.append((env_id, n, numba, actions, call, compile_s))
    rates: dict[tuple[str, int], dict[str, list[float]]] = {(c[0], c[1]): {"jax": [], "numba": []} for c in cases}
    for _ in range(int(rounds)):
        for env_id, n, numba, actions, call, _ in cases:
            rates[(env_id, n)]["numba"].append(_time_vector(numba, actions, seconds))
            rates[(env_id, n)]["jax"].append(n * steps_per_call / seconds_per_call(call, seconds))
    rows = []
    device = jax_device()
    for env_id, n, numba, _, _, compile_s in cases:
        r = rates[(env_id, n)]
        base = {"benchmark": "env stepping", "env": env_id, "num_envs": n, "unit": "env steps/s, all envs together"}
        base["pinned"] = pinned
        row = {**base, "stack": f"jax vmap + lax.scan ({steps_per_call} decisions per call)", "device": device}
        row["compile_s"] = compile_s
        _with_spread(row, "steps_per_s", r["jax"])
        rows.append(_with_spread(row, "ratio_to_numba", [j / b for j, b in zip(r["jax"], r["numba"], strict=True)]))
        rows.append(_with_spread({**base, "stack": "numba batched (vector_entry_point)"}, "steps_per_s", r["numba"]))
        numba.close()
    return rows
