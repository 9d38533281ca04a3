"""``benchmarks/jax_training/`` (SB3 vs SBX vs the fused JAX trainer): a smoke test of its
cheapest pieces on minimal budgets. The JSON it writes has the documented keys with finite
values; no speed or quality is asserted (the numbers come from the benchmark run itself)."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import pytest

pytest.importorskip("jax")
pytest.importorskip("flax")
pytest.importorskip("optax")
pytest.importorskip("sbx")
pytest.importorskip("stable_baselines3")

from benchmarks.jax_training.checkpoint import Checkpoint  # noqa: E402
from benchmarks.jax_training.quality import PROGRESS, TimedLines  # noqa: E402
from benchmarks.jax_training.speed import VMAPPED_SEEDS  # noqa: E402
from benchmarks.jax_training.stepping import env_stepping  # noqa: E402
from benchmarks.jax_training.task import ENV_ID, campaign_task  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _finite(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def test_the_task_is_the_campaign_agents_with_j_star_for_every_cell_episode():
    task = campaign_task(ENV_ID)
    assert task.campaign == "air-bearing" and task.env_id == ENV_ID
    assert task.env_kwargs == {"preset": "air-bearing-85kg"}
    assert task.seeds == list(range(20)) and task.cell == ("ab", "regulation", "none")
    assert all(j["env_id"] == ENV_ID and j["cell_env_id"] == "attitude_envs/AirBearing-v0" for j in task.jobs)
    assert all(_finite(task.j_star[s]) and task.j_star[s] > 0 for s in task.seeds)


def test_status_lines_are_timed_and_give_each_chunks_steps():
    lines = TimedLines(time.perf_counter())
    lines.write("train jax: 320/640 steps, 900 steps/s, episode return -1, eval J 2.3\ntrain jax: 64")
    lines.write("0/640 steps, 950 steps/s, episode return -1, eval J 2.2\n")
    steps = [int(PROGRESS.search(text).group(1)) for _, text in lines.lines]
    assert steps == [320, 640]
    assert all(t >= 0 for t, _ in lines.lines)


def test_env_stepping_rows_have_units_and_finite_rates():
    rows = env_stepping((ENV_ID,), sizes=(2,), seconds=0.01, rounds=1, steps_per_call=2, pinned="test")
    assert {r["stack"].split()[0] for r in rows} == {"jax", "numba"}
    for r in rows:
        assert r["unit"] == "env steps/s, all envs together" and r["pinned"] == "test" and r["num_envs"] == 2
        assert _finite(r["steps_per_s"]) and r["steps_per_s"] > 0
    jax_row = next(r for r in rows if r["stack"].startswith("jax"))
    assert _finite(jax_row["compile_s"]) and _finite(jax_row["ratio_to_numba"])


def test_the_committed_results_have_the_documented_keys():
    """The committed run (``python -m benchmarks.jax_training --out benchmarks/results``): its
    JSON has the documented keys with finite values and each target beside what was measured
    (no speed or quality is asserted: those are the run's own findings)."""
    result = json.loads((ROOT / "benchmarks" / "results" / "jax_training.json").read_text(encoding="utf-8"))
    meta = result["meta"]
    for key in ("machine", "cores", "versions", "date", "wall_s", "pinned", "jax_device", "quick"):
        assert key in meta
    assert meta["quick"] is False and _finite(meta["wall_s"]) and meta["cores"] >= 1
    for key in ("ppo_per_seed_vs_sbx", "ppo_16_seeds_vs_sbx"):
        entry = result[key]
        assert entry["env"] == ENV_ID and entry["unit"] and entry["pinned"]
        assert _finite(entry["median"]) and entry["median"] > 0
        assert len(entry["range"]) == 2 and all(_finite(v) for v in entry["range"])
    rows = result["speed"]["rows"]
    assert [r["stack"] for r in rows] == ["sb3 native", "sbx native", "jax 1 seed", f"jax {VMAPPED_SEEDS} seeds"]
    for r in rows:
        assert r["unit"].startswith("env steps/s") and all(_finite(r[k]) for k in ("steps_per_s", "ratio_to_sbx"))
    assert {"ppo_per_seed_vs_sbx", "ppo_16_seeds_vs_sbx", "compile_s"} <= set(result["targets"])
    assert all(isinstance(t["met"], bool) for t in result["targets"].values())
    # time to J/J* <= 1.05: twins pinned to one CPU and on every CPU (the target's "2 cores")
    q = result["quality"]
    assert len(q["all_cores"]) >= 2 and "sections_from_an_earlier_run" in meta
    for key in ("time_to_target", "time_to_target_all_cores"):
        assert [t["seed"] for t in q[key]] == q["training_seeds"]
        for t in q[key]:
            assert _finite(t["compile_s"]) and _finite(t["best_J_over_J_star"])
            assert (t["first_wall_s"] is None) == (not t["reached"])
    hit = result["targets"]["time_to_1.05_J_star_s"]
    assert hit["measured_per_seed"] == [t["first_wall_s"] for t in q["time_to_target_all_cores"]]
    # and again with the compilation cache filled, as the command line runs every later training
    warm = q["time_to_target_warm_cache"]
    assert [t["seed"] for t in warm] == q["training_seeds"] and all(_finite(t["compile_s"]) for t in warm)
    assert hit["measured_per_seed_warm_cache"] == [t["first_wall_s"] for t in warm]
    assert isinstance(hit["met_warm_cache"], bool)


def test_finished_sections_are_kept_and_taken_by_a_rerun_of_the_same_command(tmp_path):
    """A run that fails in a later section loses only that section: the same command on the
    same commit takes the finished ones from ``jax_training.partial.json``; another does not."""
    path = tmp_path / "jax_training.partial.json"
    key = {"command": ["--quick"], "git_revision": "abc"}
    calls = []

    def section(value):
        def fn():
            calls.append(value)
            return {"value": value}

        return fn

    first = Checkpoint(path, key)
    assert first.run("speed", section(1)) == {"value": 1}
    with pytest.raises(RuntimeError):
        first.run("quality", lambda: (_ for _ in ()).throw(RuntimeError("killed")))
    again = Checkpoint(path, key)
    assert again.run("speed", section(2)) == {"value": 1} and again.reused == ["speed"]
    assert again.run("quality", section(3)) == {"value": 3}
    assert calls == [1, 3] and set(json.loads(path.read_text())["sections"]) == {"speed", "quality"}
    other = Checkpoint(path, {**key, "git_revision": "def"})
    assert other.run("speed", section(4)) == {"value": 4} and other.reused == []
