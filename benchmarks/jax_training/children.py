"""The benchmark's child processes: fresh interpreters (:func:`experiments.processes.run_in_child`)
with JAX's persistent compilation cache off, or in a folder of the benchmark's, and XLA's
fast-compile option where the spec asks for it."""

from __future__ import annotations

import os
import sys
from typing import Any

from benchmarks.jax_training.task import ROOT
from experiments.processes import run_in_child

FAST_COMPILE_ENV = "ATTITUDE_ENVS_JAX_FAST_COMPILE"  # experiments.training.jax_training.FAST_COMPILE_ENV


def no_compile_cache() -> None:
    """No persistent compilation cache in this process (compile times are measured)."""
    os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)
    os.environ["JAX_ENABLE_COMPILATION_CACHE"] = "false"
    if "jax" in sys.modules:
        import jax

        jax.config.update("jax_enable_compilation_cache", False)


def child_env(compile_cache_dir: str | None = None) -> dict[str, str]:
    """This process's environment for a child: no persistent compilation cache, or the one in
    ``compile_cache_dir`` (the command line's own cache, in a folder of the benchmark's)."""
    env = dict(os.environ)
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    env["JAX_ENABLE_COMPILATION_CACHE"] = "false"
    if compile_cache_dir is not None:
        env["JAX_COMPILATION_CACHE_DIR"] = str(compile_cache_dir)
        env["JAX_ENABLE_COMPILATION_CACHE"] = "true"
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    return env


def run_child(target: str, spec: dict[str, Any], cpus: set[int] | None = None) -> dict[str, Any]:
    """``target(spec)`` (``"module:function"``, which calls :func:`child_setup` first) in a fresh
    interpreter on this process's CPU affinity, or ``cpus``, with :func:`child_env`; its result,
    with ``process_wall_s`` (s, interpreter start to exit)."""
    return run_in_child(target, spec, cpus=cpus, env=child_env(spec.get("compile_cache_dir")), cwd=ROOT)


def child_setup(spec: dict[str, Any]) -> None:
    """First thing in a child: no persistent compilation cache unless ``spec`` names one (its
    environment, :func:`child_env`, then does), and XLA's fast-compile option where it asks."""
    if not spec.get("compile_cache_dir"):
        no_compile_cache()
    if spec.get("fast_compile"):
        os.environ[FAST_COMPILE_ENV] = "1"
