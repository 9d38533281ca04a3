import atexit
import os
import shutil
import tempfile

import numpy as np
import pytest

import attitude_envs  # noqa: F401  (registers the ids)

# Campaigns in tests take J* from the shipped table or the solver's cache only (solving each
# test campaign's episodes would add minutes); tests that solve say so in their config.
# Set at import so module- and session-scoped fixtures and subprocesses see it too.
os.environ.setdefault("ATTITUDE_ENVS_OPTIMUM_SOLVE", "0")

# JAX's persistent compilation cache, one per test session (set before anything imports jax, so
# in-process jax and every subprocess see it): a run that builds the same SBX model as an earlier
# one, in this process or in a `train` subprocess (a resumed run, a campaign's run), loads the
# compiled XLA programs instead of compiling them again (~60 programs, half of an SBX run's CPU
# time). The programs are the same, so are the numbers. Every compile is cached (JAX's default
# keeps only those over 1 s).
if "JAX_COMPILATION_CACHE_DIR" not in os.environ:
    os.environ["JAX_COMPILATION_CACHE_DIR"] = tempfile.mkdtemp(prefix="attitude-envs-tests-jax-cache-")
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
    _owner, _cache = os.getpid(), os.environ["JAX_COMPILATION_CACHE_DIR"]
    atexit.register(lambda: os.getpid() == _owner and shutil.rmtree(_cache, ignore_errors=True))  # not forked children


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def asymmetric_inertia() -> np.ndarray:
    """A full (non-diagonal) inertia tensor meeting the triangle inequality, kg·m²."""
    return np.array([[4.0, 0.1, -0.05], [0.1, 3.5, 0.08], [-0.05, 0.08, 3.0]])


def trained_model_plays_as_evaluated(
    tmp_path, monkeypatch, env_id, overrides, total_timesteps, eval_freq, env_kwargs=None, backend: str = "jax"
):
    """PPO trained on the fused JAX trainer (fast compile; ``backend="sb3"``: on SB3) with 2
    evaluation episodes and ``overrides`` (its ``env_wrapper`` among them): ``(policy, env)``, the
    model as ``build_policy`` plays it on ``env_id``, after checking that it plays the training's
    last evaluation again (seeds 10000 and 10001), behind the wrappers' policy-side twins."""
    if backend == "jax":
        pytest.importorskip("jax")
        pytest.importorskip("flax")
        pytest.importorskip("optax")
    import gymnasium as gym

    from attitude_envs.evaluation.rollout import rollout
    from experiments.policies import build_policy
    from experiments.training.jax_training import FAST_COMPILE_ENV
    from experiments.training.training import train

    monkeypatch.setenv(FAST_COMPILE_ENV, "1")
    kwargs = dict(env_kwargs or {})
    run = tmp_path / "run"
    result = train(
        "ppo",
        env_id,
        run,
        env_kwargs=kwargs,
        total_timesteps=total_timesteps,
        overrides={**overrides, "backend": backend},
        eval_episodes=2,
        eval_freq=eval_freq,
    )
    assert result.timesteps == total_timesteps
    env = gym.make(env_id, **kwargs)
    policy = build_policy({"policy": "sb3", "model": str(run)}, env)
    last_eval = float((run / "evaluations.csv").read_text().splitlines()[-1].split(",")[1])
    played = np.mean([rollout(env, policy, seed=s)["J"] for s in (10_000, 10_001)])
    assert played == pytest.approx(last_eval, rel=1e-5)  # the training's evaluation, behind the wrapper
    return policy, env
