"""J*'s own success: the success metric decides from its measurements as it does from the infos,
J*'s replay keeps its measurements (solver cache, J* table, campaign rows), and every
leaderboard shows J* itself as an unranked line with its success and ended-early rates."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import pytest

import attitude_envs  # noqa: F401  (registers the env ids)
from attitude_envs.evaluation.success import FINAL_ERROR_DEG, FINAL_STATE_FRACTION, METRICS, metric_of
from attitude_envs.evaluation.trace import play
from baselines.base import ZeroPolicy
from experiments.campaign.store import ResultStore, optimum_outcome
from experiments.report.leaderboards import ORACLE_AGENT, best_entry, history_agents, leaderboards, oracle_success
from experiments.report.markdown import leaderboard_markdown

SHORT = {
    "attitude_envs/ReactionWheel-v0": {"episode_duration_s": 3.0},
    "attitude_envs/AirBearing-v0": {"episode_duration_s": 0.5},
    "attitude_envs/Magnetorquer-v0": {"episode_duration_s": 5.0, "control_dt_s": 1.0, "integrator_dt_s": 0.1},
    "attitude_envs/FuelSlosh-v0": {"episode_duration_s": 2.0},
    "attitude_envs/LinearSystem-v0": {"episode_steps": 30},
}


@pytest.mark.parametrize("env_id", sorted(SHORT))
def test_met_decides_as_succeeded_on_real_episodes(env_id):
    env = gym.make(env_id, **SHORT[env_id])
    metric = env.unwrapped.success_metric
    for seed in (0, 3):
        infos, _, _ = play(env, ZeroPolicy(env), seed=seed)
        first, last = infos[0], infos[-1]
        measured = metric.measurements(first, last)
        assert tuple(measured) == metric.measurement_names()
        assert metric_of(measured) is metric
        value = metric.value(first, last)
        for threshold in (None, value, value * (1 - 1e-9), value * 1.5, 0.0, metric.threshold):
            assert metric.met(measured, threshold) == metric.succeeded(first, last, threshold), (seed, threshold)
        stored = json.loads(json.dumps(measured))  # as a table stores them
        assert metric.met(stored, value) == metric.succeeded(first, last, value)


def test_met_edge_cases_and_metric_lookup():
    assert FINAL_STATE_FRACTION.met({"initial_state_norm": 0.0, "final_state_norm": 0.0}, 0.1)
    assert not FINAL_STATE_FRACTION.met({"initial_state_norm": 0.0, "final_state_norm": 1e-12}, 0.1)
    assert not FINAL_ERROR_DEG.met({"final_error_deg": float("nan")})
    assert FINAL_ERROR_DEG.met({"final_error_deg": 2.0}) and not FINAL_ERROR_DEG.met({"final_error_deg": 2.0}, 1.9)
    with pytest.raises(KeyError):
        FINAL_STATE_FRACTION.met({"final_state_norm": 1.0})
    assert metric_of(["final_error_deg"]) is FINAL_ERROR_DEG
    assert metric_of({"initial_state_norm", "final_state_norm"}) is FINAL_STATE_FRACTION
    assert metric_of(["final_error_deg", "initial_state_norm", "final_state_norm"]) is None
    assert metric_of([]) is None and set(METRICS) == {"final_error_deg", "final_state_fraction"}


# ----------------------------------------------------------------- campaign rows and leaderboards


def _row(agent, seed, J, success=True, terminated=False, **extra):
    return {"env": "mt", "scenario": "s", "fault": "none", "agent": agent, "seed": seed, "J": J}, {
        "success": success,
        "terminated": terminated,
        **extra,
    }


def _rows(outcomes, j_star=(1.0, 2.0, 3.0, 4.0)):
    """Two agents on four episodes; ``outcomes``: per seed J*'s (final error deg, terminated) or None."""
    rows = []
    for seed, (js, out) in enumerate(zip(j_star, outcomes, strict=True)):
        row = {"measurements": {"final_error_deg": out[0]}, "terminated": out[1]} if out else {}
        star = {"j_star": js, **optimum_outcome({"j_star": js, **row} if out else None)}
        for agent, factor in (("lqr", 1.5), ("ppo", 2.0), ("zero", 9.0)):
            key, rest = _row(agent, seed, js * factor)
            rows.append({**key, **rest, **star})
    return rows


def test_the_oracle_line_ends_every_board_unranked():
    rows = _rows([(1.0, False), (3.0, False), (0.5, True), (1.9, False)])
    board = leaderboards(rows)[("mt", "s", "none")]
    assert [e["agent"] for e in board] == ["lqr", "ppo", "zero", ORACLE_AGENT]
    oracle = board[-1]
    assert oracle["oracle"] and oracle["episodes"] == 4 and oracle["J_mean"] == pytest.approx(2.5)
    assert oracle["J_over_J_star"] == 1.0 and oracle["J_over_J_star_deterministic"]
    assert oracle["success_rate"] == pytest.approx(0.5)  # seeds 0 and 3; seed 2 terminated, seed 1 at 3°
    assert oracle["terminated_rate"] == pytest.approx(0.25) and oracle["success_known"] == 4
    # the campaign's threshold decides: at 3° seed 1 succeeds too
    assert leaderboards(rows, {"final_error_deg": 3.0})[("mt", "s", "none")][-1]["success_rate"] == 0.75
    text = leaderboard_markdown({("mt", "s", "none"): board})
    line = next(row for row in text.splitlines() if ORACLE_AGENT in row)
    assert line.startswith("| — | J* (oracle) | 4 (< 5 episodes) |") and "| 50 % | 25 % |" in line
    assert [row.split(" | ")[0] for row in text.splitlines() if row.startswith("| ") and "---" not in row][1:] == [
        "| 1",
        "| 2",
        "| 3",
        "| —",
    ]
    # J* is no agent: never the best analytic or learned one, never a time history
    assert best_entry(board, False, {"ppo"})["agent"] == "lqr" and best_entry(board, True, {"ppo"})["agent"] == "ppo"
    assert best_entry(board, True, set()) is None
    assert history_agents(board, set()) == ["lqr", "ppo"]


def test_unknown_oracle_measurements_give_a_dash_and_a_count():
    rows = _rows([(1.0, False), None, (0.5, False), None])
    oracle = leaderboards(rows)[("mt", "s", "none")][-1]
    assert math.isnan(oracle["success_rate"]) and math.isnan(oracle["terminated_rate"])
    assert oracle["success_known"] == 2 and oracle["terminated_known"] == 2
    line = next(r for r in leaderboard_markdown({("c", "s", "f"): [oracle]}).splitlines() if ORACLE_AGENT in r)
    assert "— (J* success: 2 of 4 episodes known)" in line and "— (J* ended early: 2 of 4 episodes known)" in line
    # rows without J* at all (no optimum joined): no oracle line
    plain = [{k: v for k, v in r.items() if not k.startswith("j_star")} for r in rows]
    assert ORACLE_AGENT not in [e["agent"] for e in leaderboards(plain)[("mt", "s", "none")]]


def test_oracle_success_reads_csv_strings_and_a_relative_metric():
    row = {"j_star": "2.0", "j_star_metric": "final_error_deg", "j_star_terminated": "False"}
    assert oracle_success({**row, "j_star_final_error_deg": "1.5"}) is True
    assert oracle_success({**row, "j_star_final_error_deg": "1.5", "j_star_terminated": "True"}) is False
    assert oracle_success({**row, "j_star_final_error_deg": "1.5", "j_star_terminated": ""}) is None
    assert oracle_success({**row, "j_star": "nan", "j_star_final_error_deg": "1.5"}) is None
    rel = {"j_star": 1.0, **optimum_outcome({"measurements": {"initial_state_norm": 4.0, "final_state_norm": 0.3}})}
    assert oracle_success(rel) is None  # terminated unknown: unknown
    out = {"measurements": {"initial_state_norm": 4.0, "final_state_norm": 0.3}, "terminated": False}
    rel = {"j_star": 1.0, **optimum_outcome(out)}
    assert rel["j_star_metric"] == "final_state_fraction" and oracle_success(rel) is True
    assert oracle_success(rel, {"final_state_fraction": 0.05}) is False


def test_store_flattens_the_optimum_outcome_into_episode_rows_and_csv(tmp_path):
    store = ResultStore(tmp_path)
    cell = ["mt", "s", "none"]
    store.append_optimum(
        {
            "hash": "a",
            "cells": [[*cell, 0]],
            "source": "table",
            "j_star": 1.0,
            "measurements": {"final_error_deg": 4.5},
            "terminated": False,
        }
    )
    store.append_optimum({"hash": "b", "cells": [[*cell, 1]], "source": "table", "j_star": 2.0})  # an older log
    for seed in (0, 1):
        store.append({"env": "mt", "scenario": "s", "fault": "none", "agent": "lqr", "seed": seed, "J": 3.0})
    again = ResultStore(tmp_path)  # from the logs
    first, second = again.sorted_rows()
    assert first["j_star_final_error_deg"] == 4.5 and first["j_star_terminated"] is False
    assert first["j_star_metric"] == "final_error_deg"
    assert second["j_star_metric"] == "" and second["j_star_terminated"] is None
    assert "j_star_final_error_deg" not in second
    header = (tmp_path / "episodes.csv").read_text().splitlines()[0].split(",")
    assert {"j_star_metric", "j_star_terminated", "j_star_final_error_deg"} <= set(header)
    oracle = leaderboards(again.sorted_rows())[("mt", "s", "none")][-1]
    assert oracle["success_known"] == 1 and math.isnan(oracle["success_rate"])


# ---------------------------------------------------------------- J*'s replay, cache and table

LS = ("LinearSystem-v0", {"episode_steps": 15}, 1, None)


@pytest.fixture
def _private_cache(tmp_path, monkeypatch):
    pytest.importorskip("casadi")
    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path / "cache"))


@pytest.mark.usefixtures("_private_cache")
def test_replay_measures_the_episode_and_old_cache_entries_still_load(tmp_path):
    from experiments import optimum

    result = optimum.solve_episode(*LS)
    env = gym.make(optimum.full_id(LS[0]), **LS[1])
    j, terminated, measured = optimum.replay_measured(env, result.actions, LS[2], LS[3])
    assert (j, terminated) == optimum.replay(env, result.actions, LS[2], LS[3]) == (result.j_star, False)
    assert measured == result.measurements and set(measured) == {"initial_state_norm", "final_state_norm"}
    infos, _, _ = play(env, ZeroPolicy(env), seed=LS[2])  # the same first info as the replay's
    assert measured["initial_state_norm"] == FINAL_STATE_FRACTION.measure(infos[0])
    # a cache entry from before measurements were kept: loads, and gets them by replaying
    (path,) = list(optimum.cache_dir().glob("*.json"))
    data = json.loads(path.read_text())
    data.pop("measurements")
    path.write_text(json.dumps(data))
    old = optimum.cached_result(*LS)
    assert old.cached and old.measurements == result.measurements and old.j_star == result.j_star
    assert "measurements" in json.loads(path.read_text())  # rewritten with them
    # one whose replay no longer gives its J* keeps measurements None
    data["j_star"] *= 1.001
    path.write_text(json.dumps(data))
    assert optimum.cached_result(*LS).measurements is None
    with pytest.raises(ValueError, match="measurements not taken"):
        optimum.with_measurements(optimum.cached_result(*LS))


@pytest.mark.usefixtures("_private_cache")
def test_add_measurements_fills_a_table_without_changing_j_star(tmp_path):
    from experiments import optimum, optimum_table

    result = optimum.solve_episode(*LS, **optimum_table.SOLVER)
    key = optimum_table.episode_key(*LS)
    entry = {"hash": optimum_table.key_hash(key), "cells": ["ls/ls/d/none/1"], "key": key, "j_star": result.j_star}
    off = {**entry, "hash": "x", "key": {**key, "seed": 2}, "j_star": 123.0}  # not this episode's J*
    table = tmp_path / "table.json"
    table.write_text(json.dumps({"about": "t", "entries": [entry, off]}, indent=1) + "\n")
    counts = optimum_table.add_measurements(table, envs=["LinearSystem-v0"], solve=True)
    assert counts["LinearSystem-v0"] == {"filled": 1, "had": 0, "mismatch": 1, "failed": 0, "skipped": 0}
    data = json.loads(table.read_text())
    filled, left = data["entries"]
    assert filled == {**entry, "measurements": result.measurements, "terminated": False}
    assert left == off and data["about"] == "t"
    again = optimum_table.add_measurements(table, envs=["LinearSystem-v0"], solve=False)
    assert again["LinearSystem-v0"]["had"] == 1 and again["LinearSystem-v0"]["skipped"] == 0
    # a campaign's J* row from the table carries them
    spec = {"hash": entry["hash"], "cells": [["ls", "d", "none", 1]]}

    class Store:
        rows: dict = {}

        def optimum_done(self, h):
            return h in self.rows

        def append_optimum(self, row):
            self.rows[row["hash"]] = row

        def optimum_row(self, h):
            return self.rows[h]

    store = Store()
    optimum_table.resolve([spec], store, None, solve=False, table=table)
    row = store.rows[entry["hash"]]
    assert row["source"] == "table" and row["measurements"] == result.measurements and row["terminated"] is False
    solved = optimum_table.solve_job(
        {**spec, **{k: v for k, v in zip(("env_id", "env_kwargs", "seed", "options"), LS, strict=True)}}
    )
    assert solved["measurements"] == result.measurements and solved["terminated"] is False


def test_write_table_writes_the_measurements_of_its_rows(tmp_path):
    pytest.importorskip("casadi")
    from experiments import optimum_table
    from experiments.campaign import episode_jobs, load_campaign

    specs = optimum_table.episode_specs(episode_jobs(load_campaign("quick"), tmp_path))[:2]

    class Inline:
        def map_unordered(self, fn, jobs):
            for i, job in enumerate(jobs):
                known = {"measurements": {"final_error_deg": 0.5}, "terminated": False} if i == 0 else {}
                row = optimum_table._result_row(job, "solved", j_star=1.5, status="Solve_Succeeded", **known)
                yield row | {"j_nlp": 1.5, "j_warm": 2.0, "warm_start": "lqr", "iterations": 3, "solve_s": 0.1}

    path, failed = optimum_table.write_table(specs, tmp_path / "t.json", Inline())
    entries = optimum_table.load_table(path)
    first, second = (entries[s["hash"]] for s in specs)
    assert not failed and first["measurements"] == {"final_error_deg": 0.5} and first["terminated"] is False
    assert "measurements" not in second and "terminated" not in second
