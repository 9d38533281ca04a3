"""The shipped J* table and J / J* in campaigns: the table covers every episode of ``quick``,
its values are reproduced by the solver, and a campaign's episodes and leaderboards carry
J* and J / J* (from a table without CasADi; solved and resumed with it; "not available"
without either)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import attitude_envs
from experiments import optimum_table
from experiments.campaign import episode_jobs, load_campaign, run_campaign
from experiments.optimum_table import INSTALL_HINT, episode_key, key_hash, load_table
from experiments.report.leaderboards import leaderboards
from experiments.report.writing import write_campaign_report

TINY_ENV = {"preset": "pyramid-4wheel", "action_frame": "body", "episode_duration_s": 3.0}
OUTAGE = [{"kind": "outage", "target": "actuator", "index": 0, "onset_s": 1.0}]


def tiny(**optimum) -> dict:
    return {
        "name": "tiny",
        "seeds": [0, 1],
        "envs": [
            {
                "name": "rw",
                "id": "attitude_envs/ReactionWheel-v0",
                "kwargs": TINY_ENV,
                "scenarios": [{"name": "random"}],
                "faults": {"none": [], "w0-out": OUTAGE},
            }
        ],
        "agents": [{"name": "zero", "policy": "zero"}, {"name": "lqr", "policy": "lqr"}],
        "optimum": optimum,
    }


def test_key_hash_is_stable_and_options_none_equals_empty():
    key = episode_key("attitude_envs/ReactionWheel-v0", {"preset": "pyramid-4wheel"}, 3, {})
    assert key == episode_key("ReactionWheel-v0", {"preset": "pyramid-4wheel"}, 3, None)
    assert key_hash(key) == "067aa38a6a7040dd87bc"  # pinned: the shipped table is keyed by it
    assert key_hash(key) != key_hash(episode_key("ReactionWheel-v0", {"preset": "pyramid-4wheel"}, 4, None))


def test_shipped_table_covers_every_quick_episode():
    quick = load_campaign("quick")
    assert quick.optimum_solve is False  # quick never solves: its J* all come from the table
    specs = optimum_table.episode_specs(episode_jobs(quick, Path("unused")))
    table = load_table()
    assert len(specs) == 30 and all(s["hash"] in table for s in specs)  # 6 cells on 5 plants × 5 seeds
    data = json.loads(optimum_table.shipped_table_path().read_text())
    assert data["oracle"] is True and data["command"] == optimum_table.COMMAND
    for e in data["entries"]:
        assert e["hash"] == key_hash(e["key"]) and math.isfinite(e["j_star"]) and e["j_star"] > 0
        assert e["status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")


def test_shipped_table_covers_every_shipped_cell():
    """--config all on a fresh machine solves no J*: every episode of the plant campaigns (and of
    the other SHIPPED cells) is in the table, and the table holds nothing else."""
    from experiments.cli import _table_specs

    specs = _table_specs(list(optimum_table.SHIPPED))
    table = load_table()
    missing = [s["labels"][0] for s in specs if s["hash"] not in table]
    assert not missing, missing
    assert set(table) == {s["hash"] for s in specs}
    from attitude_envs.registration import CONSTRAINED_ENV_IDS

    ids = {name.split("/")[-1] for name in (*attitude_envs.ENV_IDS, *CONSTRAINED_ENV_IDS)}
    assert {s["key"]["env_id"] for s in specs} == ids


def test_shipped_entries_are_reproduced_by_the_solver(tmp_path, monkeypatch):
    pytest.importorskip("casadi")
    from experiments import optimum

    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path / "cache"))
    entries = json.loads(optimum_table.shipped_table_path().read_text())["entries"]
    fastest = sorted(entries, key=lambda e: e["solve_s"])[:2]  # short solves, different seeds or faults
    for e in fastest:
        k = e["key"]
        r = optimum.solve_episode(k["env_id"], k["env_kwargs"], k["seed"], k["options"], cache=False)
        assert r.solved, (e["readable"], r.status)
        assert abs(r.j_star - e["j_star"]) <= 1e-6 * abs(e["j_star"]), (e["readable"], r.j_star, e["j_star"])


def _tiny_table(path: Path, config: dict, j_star: float) -> Path:
    specs = optimum_table.episode_specs(episode_jobs(load_campaign(config), path.parent))
    entries = [{"hash": s["hash"], "key": s["key"], "j_star": j_star} for s in specs]
    path.write_text(json.dumps({"entries": entries}))
    return path


def test_campaign_report_has_j_over_j_star_from_a_table(tmp_path, monkeypatch):
    # no solver needed: a table holds every episode (as the shipped one does for quick)
    monkeypatch.setattr(optimum_table, "solver_unavailable", lambda: INSTALL_HINT)
    table = _tiny_table(tmp_path / "table.json", tiny(), j_star=2.5)
    result = run_campaign(tiny(solve=False, table=str(table)), tmp_path / "out", workers=1)
    assert len(result.rows) == 8 and not result.optimum_notes
    for r in result.rows:
        assert r["j_star"] == 2.5 and r["j_star_source"] == "table"
        assert r["j_over_j_star"] == pytest.approx(r["J"] / 2.5, rel=1e-12)
    board = leaderboards(result.rows)[("rw", "random", "w0-out")]
    assert all(np.isfinite(e["J_over_J_star"]) for e in board)
    report = write_campaign_report(result).read_text()
    assert "| J / J* |" in report and "J* is an oracle" in report and "knows its faults" in report
    lqr_line = next(line for line in report.splitlines() if " | lqr | " in line)
    ratio = lqr_line.split(" | ")[6]
    assert ratio != "—" and float(ratio.split()[0]) > 0
    # J* itself, unranked and last; this table has no measurements: its success is unknown
    assert board[-1]["agent"] == "J* (oracle)" and board[-1]["J_mean"] == 2.5
    oracle_line = next(line for line in report.splitlines() if "| J* (oracle) |" in line)
    assert oracle_line.startswith("| — |") and "— (J* success: 0 of 2 episodes known)" in oracle_line
    # the csv carries the columns too
    header = (tmp_path / "out" / "episodes.csv").read_text().splitlines()[0].split(",")
    assert {"j_star", "j_over_j_star", "j_star_source"} <= set(header)


def test_without_casadi_or_table_j_star_is_not_available(tmp_path, monkeypatch):
    monkeypatch.setattr(optimum_table, "solver_unavailable", lambda: INSTALL_HINT)
    result = run_campaign(tiny(table=str(tmp_path / "none.json")), tmp_path / "out", workers=1)
    assert all(math.isnan(r["j_star"]) and r["j_star_source"] == "missing" for r in result.rows)
    report = write_campaign_report(result).read_text()
    assert INSTALL_HINT in report and "| — |" in report


def test_campaign_solves_j_star_once_per_episode_and_resumes(tmp_path, monkeypatch):
    pytest.importorskip("casadi")
    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path / "cache"))
    calls = []
    real = optimum_table.solve_job
    monkeypatch.setattr(optimum_table, "solve_job", lambda job: calls.append(job["hash"]) or real(job))
    config = tiny(solve=True, table=str(tmp_path / "none.json"))
    first = run_campaign(config, tmp_path / "out", workers=1)
    assert len(calls) == 4 == len(set(calls))  # 2 faults × 2 seeds, shared by both agents
    for r in first.rows:
        assert r["j_star_source"] == "solved" and np.isfinite(r["j_star"])
        assert r["j_over_j_star"] >= 1.0 - 1e-6  # the oracle is a lower bound on every agent
    lines = (tmp_path / "out" / "optimum.jsonl").read_text().splitlines()
    assert len(lines) == 4
    again = run_campaign(config, tmp_path / "out", workers=1)  # resumed: nothing solved again
    assert len(calls) == 4 and [r["j_star"] for r in again.rows] == [r["j_star"] for r in first.rows]
    # J*'s own outcome: measured on its replay, joined into every row, judged on the leaderboard
    for r in again.rows:
        assert r["j_star_metric"] == "final_error_deg" and r["j_star_terminated"] is False
        assert r["j_star_final_error_deg"] >= 0.0
    oracle = leaderboards(again.rows)[("rw", "random", "none")][-1]
    met = [r["j_star_final_error_deg"] <= 2.0 for r in again.rows if r["fault"] == "none" and r["agent"] == "lqr"]
    assert oracle["agent"] == "J* (oracle)" and oracle["success_rate"] == pytest.approx(np.mean(met))


def test_optimum_config_is_validated():
    with pytest.raises(ValueError, match="optimum must be a mapping"):
        load_campaign({**tiny(), "optimum": {"solve": True, "bogus": 1}})
    with pytest.raises(ValueError, match="optimum.solve must be true or false"):
        load_campaign({**tiny(), "optimum": {"solve": "yes"}})


def test_j_over_j_star_is_a_ratio_of_means_with_a_paired_ci():
    from experiments.report.statistics import ratio_stats

    rows = [{"J": 2.0, "j_star": 1.0}, {"J": 6.0, "j_star": 4.0}, {"J": 0.5, "j_star": 1e-4}, {"J": 3.0}]
    s = ratio_stats(rows)
    assert s["J_over_J_star"] == pytest.approx(8.5 / 5.0001)  # not the mean ratio (~1667)
    assert s["J_over_J_star_episodes"] == 3  # the episode without a J* is left out
    assert s["J_over_J_star_median"] == pytest.approx(2.0)
    assert s["J_over_J_star_ci_low"] <= s["J_over_J_star"] <= s["J_over_J_star_ci_high"]
    same = ratio_stats([{"J": 2.0, "j_star": 1.0}, {"J": 4.0, "j_star": 2.0}])
    assert same["J_over_J_star_deterministic"] and same["J_over_J_star"] == pytest.approx(2.0)
    assert ratio_stats([{"J": 1.0}])["J_over_J_star_episodes"] == 0


def test_write_table_keeps_what_the_table_holds_and_solves_the_rest(tmp_path):
    """--keep-table: keys the existing table holds (same solver settings) are copied, only the
    others are solved; a table of other settings keeps nothing."""
    pytest.importorskip("casadi")
    from experiments.cli import _table_specs

    specs = _table_specs(["quick:ls"])
    keep = optimum_table.reusable_entries(optimum_table.shipped_table_path())
    assert all(s["hash"] in keep for s in specs)
    new_key = optimum_table.episode_specs(
        [{**j, "key": {**j["key"], "seed": 99}} for j in episode_jobs(load_campaign("quick"), tmp_path)[:1]]
    )

    class Inline:
        solved: list = []

        def map_unordered(self, fn, jobs):
            for job in jobs:
                self.solved.append(job["hash"])
                yield {
                    **optimum_table._result_row(job, "solved", j_star=1.5, status="Solve_Succeeded"),
                    "j_nlp": 1.5,
                    "j_warm": 2.0,
                    "warm_start": "lqr",
                    "iterations": 3,
                    "solve_s": 0.1,
                }

    path, failed = optimum_table.write_table(specs + new_key, tmp_path / "t.json", Inline(), keep=keep)
    assert not failed and Inline.solved == [new_key[0]["hash"]]
    written = load_table(path)
    assert set(written) == {s["hash"] for s in specs + new_key}
    for s in specs:
        assert written[s["hash"]]["j_star"] == keep[s["hash"]]["j_star"]
    # the other cells' entries of the file go only with keep_others (the CLI's --keep-table): a
    # table written for some cells does not drop the rest
    others = {h for h in keep if h not in {s["hash"] for s in specs}}
    assert others and not others & set(written)
    both, _ = optimum_table.write_table(specs, tmp_path / "both.json", Inline(), keep=keep, keep_others=True)
    assert set(load_table(both)) == set(keep)
    assert all(load_table(both)[h]["j_star"] == keep[h]["j_star"] for h in keep)
    data = json.loads(path.read_text())
    data["solver"]["tol"] = 1e-6
    path.write_text(json.dumps(data))
    assert optimum_table.reusable_entries(path) == {}
    assert optimum_table.reusable_entries(tmp_path / "none.json") == {}
