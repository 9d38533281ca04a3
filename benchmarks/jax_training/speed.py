"""The speed section: env steps/s of training PPO with SB3, SBX and the fused trainer (one seed
and vmapped seeds) in alternating rounds, pinned, and the fused rows again on every CPU."""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np

from benchmarks.env_speed import _median_range, _with_spread
from benchmarks.jax_training.children import FAST_COMPILE_ENV, child_setup, run_child
from benchmarks.jax_training.task import recipe

VMAPPED_SEEDS = 16


def jax_trainers(env_id: str, env_kwargs: dict[str, Any], rollouts: int, seeds: int) -> dict[str, Any]:
    """The fused trainer of ``env_id``'s recipe for one seed (``train``'s own compiled program,
    :func:`experiments.training.jax_training.program`) and for ``seeds`` vmapped seeds, compiled and
    warmed up by one chunk of ``rollouts`` updates: name → ``{"step": () -> env steps,
    "compile_s", "seeds", "device"}``. The schedules' horizon is set far out (1e12 steps), so the
    learning rate stays positive however many rounds run."""
    import jax
    import jax.numpy as jnp

    from agents.fused_ppo.config import as_float32, from_zoo, stack_hparams
    from agents.fused_ppo.trainer import make_chunked
    from experiments.training.jax_training import compiler_options, program

    config, hp = from_zoo(recipe(env_id))
    hp = as_float32(hp._replace(schedule_timesteps=1e12))
    n = jnp.asarray(int(rollouts), jnp.int32)
    out: dict[str, Any] = {}

    prog = program(env_id, env_kwargs, config)
    before = prog.compile_s
    single = {"state": prog.init(jax.random.PRNGKey(0), hp)}

    def step_single() -> int:
        single["state"], _ = prog.update_chunk(single["state"], hp, int(rollouts))
        jax.block_until_ready(single["state"])
        return int(rollouts) * config.rollout_size

    step_single()  # compiles update_chunk (on first use), then runs one chunk
    out["jax 1 seed"] = {"step": step_single, "compile_s": prog.compile_s - before, "seeds": 1}

    chunked = make_chunked(prog.env, prog.env_params, config)
    keys = jnp.stack([jax.random.PRNGKey(s) for s in range(int(seeds))])
    hps = stack_hparams([hp] * int(seeds))
    start = time.perf_counter()
    options = compiler_options()
    init = jax.jit(jax.vmap(chunked.init), compiler_options=options).lower(keys, hps).compile()
    vstate = {"state": init(keys, hps)}
    vchunk = jax.vmap(chunked.update_chunk, in_axes=(0, 0, None))
    chunk = jax.jit(vchunk, compiler_options=options).lower(vstate["state"], hps, n).compile()
    compile_s = time.perf_counter() - start

    def step_vmapped() -> int:
        vstate["state"], _ = chunk(vstate["state"], hps, n)
        jax.block_until_ready(vstate["state"])
        return int(seeds) * int(rollouts) * config.rollout_size

    step_vmapped()
    out[f"jax {seeds} seeds"] = {"step": step_vmapped, "compile_s": compile_s, "seeds": int(seeds)}
    for entry in out.values():
        entry["device"] = str(jax.devices()[0])
    return out


def jax_rates(spec: dict[str, Any]) -> dict[str, Any]:
    """A child process (:func:`~benchmarks.jax_training.children.run_child`): the fused trainer's
    rates on its CPUs (the all-cores row)."""
    child_setup(spec)
    trainers = jax_trainers(spec["env_id"], spec["env_kwargs"], spec["rollouts"], spec["seeds"])
    rates: dict[str, list[float]] = {name: [] for name in trainers}
    for _ in range(int(spec["rounds"])):
        for name, t in trainers.items():
            start = time.perf_counter()
            steps = t["step"]()
            rates[name].append(steps / (time.perf_counter() - start))
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    return {
        "cpus": cpus,
        "stacks": {
            name: {"rates": rates[name], "compile_s": t["compile_s"], "seeds": t["seeds"], "device": t["device"]}
            for name, t in trainers.items()
        },
    }


def speed(
    env_id: str, env_kwargs: dict[str, Any], rollouts: int, rounds: int, pinned: str, all_cores: set[int] | None
) -> dict[str, Any]:
    """The speed section of ``env_id``'s PPO recipe (module docstring): rows, ratios, compile times."""
    import torch

    from benchmarks.training_throughput import _model

    torch.set_num_threads(1)
    config_rollout = int(recipe(env_id)["n_envs"]) * int(recipe(env_id)["n_steps"])
    per_round = int(rollouts) * config_rollout
    stacks: dict[str, dict[str, Any]] = {}
    for backend in ("sb3", "sbx"):
        model = _model("ppo", env_id, env_kwargs, backend, native=True)
        start = time.perf_counter()
        model.learn(per_round)  # warm-up: SBX jit-compiles its update here
        warm = time.perf_counter() - start

        def step(model=model) -> int:
            done = model.num_timesteps
            model.learn(per_round, reset_num_timesteps=False)
            return int(model.num_timesteps - done)

        stacks[f"{backend} native"] = {"step": step, "warmup_s": warm, "seeds": 1, "device": "cpu (torch)"}
    stacks["sbx native"]["device"] = jax_device()
    stacks.update(jax_trainers(env_id, env_kwargs, rollouts, VMAPPED_SEEDS))
    rates: dict[str, list[float]] = {name: [] for name in stacks}
    for _ in range(int(rounds)):
        for name, s in stacks.items():
            start = time.perf_counter()
            steps = s["step"]()
            rates[name].append(steps / (time.perf_counter() - start))
    sbx, sb3 = rates["sbx native"], rates["sb3 native"]
    rows = []
    for name, values in rates.items():
        s = stacks[name]
        row = {
            "benchmark": "train ppo (rollouts + updates, no evaluation)",
            "env": env_id,
            "stack": name,
            "seeds": s["seeds"],
            "env_steps_per_round_per_seed": per_round,
            "unit": "env steps/s" + (", all seeds together" if s["seeds"] > 1 else ""),
            "pinned": pinned,
            "device": s["device"],
        }
        _with_spread(row, "steps_per_s", values)
        _with_spread(row, "ratio_to_sbx", [v / r for v, r in zip(values, sbx, strict=True)])
        rows.append(_with_spread(row, "ratio_to_sb3", [v / r for v, r in zip(values, sb3, strict=True)]))
    vmapped = f"jax {VMAPPED_SEEDS} seeds"
    ratios = {
        "ppo_per_seed_vs_sbx": ratio_entry(rates["jax 1 seed"], sbx, env_id, pinned, "fused PPO 1 seed / SBX 1 seed"),
        "ppo_16_seeds_vs_sbx": ratio_entry(
            rates[vmapped], sbx, env_id, pinned, f"fused PPO {VMAPPED_SEEDS} vmapped seeds (aggregate) / SBX 1 seed"
        ),
    }
    compile_rows = []
    for name, s in stacks.items():
        key = "compile_s" if "compile_s" in s else "warmup_s"
        what = (
            "XLA compile of the init and update_chunk programs (ahead of time)"
            if key == "compile_s"
            else f"first learn() of {per_round} env steps (SBX: its jit compile included)"
        )
        compile_rows.append(
            {
                "env": env_id,
                "stack": name,
                key: s[key],
                "unit": "s",
                "what": what,
                "pinned": pinned,
                "device": s["device"],
            }
        )
    out = {"env": env_id, "env_kwargs": env_kwargs, "rows": rows, "compile": compile_rows, **ratios}
    if all_cores:
        child = run_child(
            "benchmarks.jax_training.speed:jax_rates",
            {
                "env_id": env_id,
                "env_kwargs": env_kwargs,
                "rollouts": int(rollouts),
                "seeds": VMAPPED_SEEDS,
                "rounds": int(rounds),
                "fast_compile": os.environ.get(FAST_COMPILE_ENV, "") not in ("", "0"),
            },
            cpus=all_cores,
        )
        sbx_median = float(np.median(sbx))
        all_rows = []
        for name, s in child["stacks"].items():
            row = {
                "benchmark": "train ppo (rollouts + updates, no evaluation)",
                "env": env_id,
                "stack": name,
                "seeds": s["seeds"],
                "unit": "env steps/s" + (", all seeds together" if s["seeds"] > 1 else ""),
                "pinned": f"no: all {len(child['cpus'])} CPUs {child['cpus']} (a child process, its own rounds)",
                "device": s["device"],
                "compile_s": s["compile_s"],
            }
            _with_spread(row, "steps_per_s", s["rates"])
            row["ratio_to_pinned_sbx_median"] = row["steps_per_s"] / sbx_median
            all_rows.append(row)
        out["jax_all_cores"] = all_rows
    return out


def ratio_entry(values: list[float], reference: list[float], env_id: str, pinned: str, what: str) -> dict[str, Any]:
    row = {"env": env_id, "what": what, "unit": "ratio of env steps/s (per-round ratios)", "pinned": pinned}
    median, spread = _median_range([v / r for v, r in zip(values, reference, strict=True)])
    return {**row, "median": median, "range": spread, "rounds": len(values)}


def jax_device() -> str:
    import jax

    return str(jax.devices()[0])
