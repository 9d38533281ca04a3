"""The robustness curves' protocol (benchmarks/robustness.py) on a short episode."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

from benchmarks import robustness

pytest.importorskip("casadi")

DOCS = Path(__file__).resolve().parents[1] / "docs" / "campaigns"
#: a few steps of each new plant's cell (its period kept), for runs that play every axis
SHORT = {
    "linear": ("lqr-dare", {"episode_steps": 200}),
    "slosh": ("slosh-lqr+kf", {"episode_duration_s": 1.0}),
    "magnetorquer": ("amnftsmc+mekf", {"episode_duration_s": 6.0}),
}


def _fake_models(root: Path, entry: str, name: str, seeds=(0, 1, 2)) -> None:
    """Empty best snapshots where the campaign trains ``name`` on ``entry`` (found, never loaded)."""
    for seed in seeds:
        best = root / "models" / entry / name / f"seed{seed}" / "best"
        best.mkdir(parents=True)
        (best / "model.zip").write_bytes(b"")


def test_cvar_is_the_mean_of_the_worst_tenth():
    ratios = np.arange(1.0, 21.0)
    assert robustness.cvar(ratios) == pytest.approx((20.0 + 19.0) / 2)
    assert robustness.cvar(np.array([1.5])) == 1.5


@pytest.mark.parametrize("plant", sorted(robustness.PLANTS))
def test_every_point_has_the_flight_sensors_and_one_feature(plant):
    points = robustness.axes(plant)
    assert {a for a, _, _ in points} == {"parameters", "delay", "noise", "held-out"}
    held_out = [(level, c) for a, level, c in points if a == "held-out"]
    # the flight cells' conditions, then their parameter tolerances widened beyond training's
    assert held_out == [
        (1.0, "flight"),
        (2.0, {"base": "flight", "parameters": 2.0}),
        (4.0, {"base": "flight", "parameters": 4.0}),
    ]
    for axis, level, conditions in points:
        if axis == "held-out":
            continue
        assert conditions["sensors"] == (level if axis == "noise" else 1.0)
        assert set(conditions) - {"sensors"} == ({"parameters"} if axis == "parameters" else set()) | (
            {"delay_steps"} if axis == "delay" else set()
        )
        robustness.Conditions.from_config(conditions)  # every point is a valid conditions dict


@pytest.mark.parametrize(
    ("plant", "tolerance"),
    [
        ("wheel", 0.05),  # the inertia moments
        ("air-bearing", 0.05),
        ("magnetorquer", 0.05),
        ("slosh", 0.15),  # the slosh masses and pendulum lengths
        ("linear", 0.05),  # B's input gains
    ],
)
def test_a_parameters_level_is_an_error_of_the_plants_named_tolerance(plant, tolerance):
    assert robustness.parameter_tolerance(plant) == tolerance
    scales = [c["parameters"] for a, _, c in robustness.axes(plant) if a == "parameters"]
    assert scales == pytest.approx([p / tolerance for p in robustness.PARAMETER_LEVELS])


def test_linear_parameters_level_draws_the_input_gains_within_it():
    """At 50 % the drawn gains of B's columns spread over ±50 %, not the flight table's ±5 %."""
    conditions = next(c for a, lv, c in robustness.axes("linear") if a == "parameters" and lv == 0.5)
    env = gym.make("attitude_envs/LinearSystem-v0", conditions=conditions, preset="heravi-2017")
    gains = []
    for seed in range(8):
        env.reset(seed=seed)
        gains.append(env.unwrapped.drawn_parameters()["actuator_gain"])
    gains = np.concatenate(gains)
    assert np.all(np.abs(gains - 1.0) <= 0.5) and np.max(np.abs(gains - 1.0)) > 0.2


def test_a_level_the_conditions_cannot_express_is_refused(monkeypatch):
    monkeypatch.setattr(robustness, "PARAMETER_LEVELS", (0.0, 0.6))
    with pytest.raises(ValueError, match=r"wheel parameters axis cannot reach 60 %.*above 10"):
        robustness.axes("wheel")
    # the magnetorquer's dipoles (±10 %) reach ±100 % at its top level: the page says so
    words = robustness.scaled_tolerances("magnetorquer", robustness.parameter_scale("magnetorquer", 0.5))
    assert words == [
        "principal axes ±20°",
        "actuator scale factors ±100 % / 50 % (±100 % draws an actuator's gain down to zero)",
    ]
    assert robustness.scaled_tolerances("linear", 10.0) == []


def test_a_short_run_writes_rows_and_resumes(tmp_path):
    out = tmp_path / "robustness.csv"
    kwargs = {"episode_duration_s": 2.0, "control_dt_s": 0.5}
    rows = robustness.run("wheel", 1, out, ["lqr"], env_kwargs=kwargs)
    assert len(rows) == len(robustness.axes("wheel"))
    assert [r["axis"] for r in rows][-3:] == ["held-out"] * 3
    for row in rows:
        assert row["j_over_j_star"] >= 1.0 - 1e-9  # no controller beats the oracle
    written = list(csv.DictReader(out.open()))
    assert [r["axis"] for r in written] == [r["axis"] for r in rows]
    assert set(written[0]) == {"agent", "axis", "level", "j_over_j_star", "cvar10", "seeds"}
    episodes = out.with_suffix(".episodes.jsonl").read_text().splitlines()
    again = robustness.run("wheel", 1, out, ["lqr"], env_kwargs=kwargs)  # resumes: nothing replayed
    assert out.with_suffix(".episodes.jsonl").read_text().splitlines() == episodes
    assert [r["j_over_j_star"] for r in again] == [r["j_over_j_star"] for r in rows]


@pytest.mark.parametrize("plant", sorted(SHORT))
def test_each_new_plant_plays_every_point(plant, tmp_path, monkeypatch):
    """An analytic agent of each new plant over every axis on a few steps (J* stubbed: no solve)."""
    solved = []
    monkeypatch.setattr(
        robustness, "j_star", lambda env_id, conditions, seed, kwargs, warm=None: solved.append(env_id) or 1.0
    )
    name, kwargs = SHORT[plant]
    rows = robustness.run(plant, 1, tmp_path / "robustness.csv", [name], env_kwargs=kwargs)
    assert [(r["axis"], r["level"]) for r in rows] == [(a, lv) for a, lv, _ in robustness.axes(plant)]
    assert all(np.isfinite(r["j_over_j_star"]) for r in rows)
    assert set(solved) == {robustness.PLANTS[plant]}  # J* on the campaign's cell


def test_the_committed_gyrostat_records_read_back_unchanged(tmp_path):
    """The wheel and air-bearing pages' episodes resume as they are (same agents, axes, levels,
    keys): nothing replayed, nothing solved, the committed rows again."""
    for plant in ("wheel", "air-bearing"):
        out = tmp_path / plant / "robustness.csv"
        out.parent.mkdir()
        record = out.with_suffix(".episodes.jsonl")
        shutil.copy(DOCS / plant / "robustness.episodes.jsonl", record)
        committed = list(csv.DictReader((DOCS / plant / "robustness.csv").open()))
        names = list(dict.fromkeys(r["agent"] for r in committed))  # the page's agents, in its order
        for name in set(names) & set(robustness.learned_agents(plant)):
            _fake_models(tmp_path / plant, robustness.training_entry(plant, name), name)
        before = record.read_text()
        rows = robustness.run(plant, 20, out, names, models=tmp_path / plant)
        assert record.read_text() == before
        assert [(r["agent"], r["axis"], float(r["level"])) for r in committed] == [
            (r["agent"], r["axis"], r["level"]) for r in rows
        ]
        for old, new in zip(committed, rows, strict=True):
            assert float(old["j_over_j_star"]) == pytest.approx(new["j_over_j_star"], rel=1e-12)
            assert float(old["cvar10"]) == pytest.approx(new["cvar10"], rel=1e-12)


def test_the_agents_are_campaign_rows():
    for plant in robustness.PLANTS:
        lab, flight_cell = robustness.cells(plant)
        assert lab.id == flight_cell.id == robustness.PLANTS[plant]
        for name in robustness.agents(plant):
            assert robustness.campaign_row(plant, name).train is None
        learned = robustness.learned_agents(plant)
        assert {"ppo", "ppo-flight"} <= set(learned)
        assert all(robustness.campaign_row(plant, name).train is not None for name in learned)
    assert robustness.agents("wheel") == robustness.agents("air-bearing") == ["lqr", "lqr+mekf", "lqr-delay+mekf"]
    assert robustness.agents("linear") == ["lqr-dare", "linear-lqr+kf"]
    assert robustness.agents("slosh") == ["slosh-lqr", "slosh-lqr+kf"]
    assert robustness.agents("magnetorquer") == ["amnftsmc", "amnftsmc+mekf", "mpc"]
    assert "ppo-flight-10hz" in robustness.learned_agents("air-bearing")
    assert "ppo-flight-1hz" in robustness.learned_agents("linear")
    # the models_of rows (acting through an estimator) are not trained rows
    assert "ppo-flight+kf" not in robustness.learned_agents("linear")


def test_an_unknown_agent_names_the_accepted_ones(tmp_path):
    with pytest.raises(ValueError, match=r"--agents \['lqr'\] unknown; accepted: \['lqr-dare', 'linear-lqr\+kf'"):
        robustness.run("linear", 1, tmp_path / "r.csv", ["lqr"])
    with pytest.raises(ValueError, match=r"--agents \['ppo'\] unknown.*need --models"):
        robustness.run("slosh", 1, tmp_path / "r.csv", ["ppo"])
    with pytest.raises(ValueError, match=r"plant must be one of .*'wheel'.*got 'rw'"):
        robustness.axes("rw")


def test_learned_agents_need_the_campaign_models(tmp_path):
    with pytest.raises(ValueError, match=r"--models .* has no trained ppo, .* of the wheel campaign"):
        robustness.learned_models("wheel", tmp_path)
    _fake_models(tmp_path, "ls-flight", "ppo-flight-1hz", seeds=(0, 1))
    with pytest.raises(
        ValueError, match=r"no trained ppo-flight-1hz of the linear campaign: .*ls-flight/ppo-flight-1hz/seed2/final"
    ):
        robustness.learned_models("linear", tmp_path, ["ppo-flight-1hz"])


def test_learned_agents_are_every_training_seeds_best_snapshot(tmp_path):
    """Where the wheel campaign trains them: the lab PPO on its lab entry, the flight PPO on its
    flight entry, one run per training seed (0, 1, 2)."""
    for entry, name in (("rw", "ppo"), ("rw-flight", "ppo-flight")):
        for seed in (0, 1, 2):
            run = tmp_path / "models" / entry / name / f"seed{seed}"
            (run / "final").mkdir(parents=True)
            (run / "final" / "model.zip").write_bytes(b"")
            if seed == 0:  # a best snapshot where one was saved, else the final one
                (run / "best").mkdir()
                (run / "best" / "model.zip").write_bytes(b"")
    found = robustness.learned_models("wheel", tmp_path, ["ppo", "ppo-flight"])
    assert {k: [(s, p.relative_to(tmp_path).as_posix()) for s, p in v] for k, v in found.items()} == {
        "ppo": [
            (0, "models/rw/ppo/seed0/best/model.zip"),
            (1, "models/rw/ppo/seed1/final/model.zip"),
            (2, "models/rw/ppo/seed2/final/model.zip"),
        ],
        "ppo-flight": [
            (0, "models/rw-flight/ppo-flight/seed0/best/model.zip"),
            (1, "models/rw-flight/ppo-flight/seed1/final/model.zip"),
            (2, "models/rw-flight/ppo-flight/seed2/final/model.zip"),
        ],
    }
    (tmp_path / "models" / "rw-flight" / "ppo-flight" / "seed2" / "final" / "model.zip").unlink()
    with pytest.raises(ValueError, match=r"no trained ppo-flight of the wheel campaign: .*seed2/final/model.zip"):
        robustness.learned_models("wheel", tmp_path, ["ppo", "ppo-flight"])


def test_a_learned_agent_plays_on_its_campaign_play_env(tmp_path, monkeypatch):
    """linear's ppo-flight-1hz decides every 1 s on LinearSystem-v1 (its row's env_kwargs), each
    training seed's model, under the point's conditions; J* stays the cell's (LinearSystem-v0)."""
    from baselines.base import ZeroPolicy

    _fake_models(tmp_path, "ls-flight", "ppo-flight-1hz")
    built = []

    def factory(spec, name):
        def build(env):
            built.append((spec, env.spec.id, env.unwrapped.control_dt_s, env.unwrapped.conditions.delay_steps))
            return ZeroPolicy(env)

        return build

    monkeypatch.setattr(robustness, "_factory", factory)
    monkeypatch.setattr(
        robustness, "j_star", lambda env_id, conditions, seed, kwargs, warm=None: 1.0 if "-v0" in env_id else 0
    )
    out = tmp_path / "robustness.csv"
    rows = robustness.run(
        "linear", 1, out, ["ppo-flight-1hz"], models=tmp_path, axes_chosen=["delay"], env_kwargs={"episode_steps": 200}
    )
    assert [r["level"] for r in rows] == [0.0, 1.0, 2.0, 3.0]
    assert {(i, dt) for _, i, dt, _ in built} == {("attitude_envs/LinearSystem-v1", 1.0)}
    assert sorted({d for *_, d in built}) == [0, 1, 2, 3]
    models = sorted({spec["model"] for spec, *_ in built})
    assert models == [str(tmp_path / f"models/ls-flight/ppo-flight-1hz/seed{s}/best/model.zip") for s in (0, 1, 2)]
    assert all(spec["policy"] == "sb3" for spec, *_ in built)
    episodes = [json.loads(line) for line in out.with_suffix(".episodes.jsonl").read_text().splitlines()]
    assert sorted({e["train_seed"] for e in episodes}) == [0, 1, 2]


def test_the_page_names_each_plants_parameter_and_periods():
    rows, episodes = [], []
    for name in ("lqr-dare", "ppo-flight-1hz"):
        for axis, level, _ in robustness.axes("linear"):
            rows.append({"agent": name, "axis": axis, "level": level, "j_over_j_star": 1.1, "cvar10": 1.2, "seeds": 2})
            episodes += [
                {"agent": name, "axis": axis, "level": level, "seed": s, "j": 2.2, "j_star": 2.0} for s in (0, 1)
            ]
    text = " ".join(robustness.page(rows, "linear", episodes).split())  # the page's lines wrapped or not
    assert "the true input gains (each column of B) drawn within ± that relative error" in text
    assert "LinearSystem's only flight parameter tolerance" in text
    assert "0.01 s for `lqr-dare` (LinearSystem-v0); 1 s for `ppo-flight-1hz` (LinearSystem-v1)" in text
    assert "the distribution `ppo-flight-1hz` trained on" in text
    assert "--agents lqr-dare ppo-flight-1hz" in text  # not every agent: the command says which
    assert "inertia" not in text
    mt_rows = [dict(r, agent="mpc") for r in rows if r["agent"] == "lqr-dare"]
    text = " ".join(robustness.page(mt_rows, "magnetorquer", [dict(e, agent="mpc") for e in episodes]).split())
    assert "the true inertia drawn within ± that relative error" in text
    assert "draws an actuator's gain down to zero" in text
    assert "3 s for `mpc` (Magnetorquer-v0)" in text


def test_delayed_and_held_out_optima_start_from_the_point_before(monkeypatch):
    """Delay d ≥ 2 starts from the d − 1 optimum's commands one period earlier; a held-out
    scale k > 1 from the optimum at k / 2, down to the flight cell's."""
    calls = []

    def solve(env_id, kwargs, seed, warm_start="lqr"):
        conditions = kwargs["conditions"]
        calls.append((conditions, None if isinstance(warm_start, str) else warm_start.copy()))
        level = len(calls)  # each solve's actions: its call number, step by step
        return SimpleNamespace(actions=np.arange(4.0)[:, None] + 10 * level, j_star=float(level))

    monkeypatch.setattr(robustness.optimum, "solve_episode", solve)
    env = robustness.PLANTS["slosh"]
    plant = robustness.Conditions.from_config({"delay_steps": 3}).as_dict()
    assert robustness._optimum(env, {"conditions": plant}, 0).j_star == 3.0
    assert [c["delay_steps"] for c, _ in calls] == [1, 2, 3]
    assert calls[0][1] is None
    np.testing.assert_array_equal(calls[1][1][:, 0], [11.0, 12.0, 13.0, 13.0])  # shifted one period
    np.testing.assert_array_equal(calls[2][1][:, 0], [21.0, 22.0, 23.0, 23.0])
    calls.clear()
    held_out = robustness.Conditions.from_config({"base": "flight", "parameters": 4.0}).as_dict()
    robustness._optimum(env, {"conditions": held_out}, 0)
    assert [c if isinstance(c, str) else c["parameters"] for c, _ in calls] == ["flight", 2.0, 4.0]
    np.testing.assert_array_equal(calls[1][1][:, 0], [10.0, 11.0, 12.0, 13.0])  # not shifted
    calls.clear()
    robustness._optimum(env, {"conditions": robustness.Conditions.from_config({"parameters": 2.0}).as_dict()}, 0)
    assert len(calls) == 1 and calls[0][1] is None  # the parameters axis: the default warm start


def test_slosh_optima_start_from_the_warm_agents_closed_loop(tmp_path, monkeypatch):
    """With the campaign's models, a FuelSlosh J* outside the shipped table starts from the
    closed loop of ppo-flight's first training seed at the cell's period, played on the episode
    under the point's conditions (its sensors on), zero after an early end; the oracle's
    problem has no sensors."""
    from baselines.base import ZeroPolicy

    class FullThrottle(ZeroPolicy):  # crosses a limit within a few decisions
        def act(self, obs, info):
            return np.ones(2)

    _fake_models(tmp_path, "fs-flight", "ppo-flight")
    played = []

    def factory(spec, name):
        def build(env):
            played.append((name, spec.get("model"), env.unwrapped.control_dt_s, env.unwrapped.conditions.parameters))
            return FullThrottle(env) if name == "ppo-flight" else ZeroPolicy(env)

        return build

    solved = []

    def solve(env_id, kwargs, seed, warm_start="lqr"):
        solved.append((env_id, kwargs["conditions"], np.asarray(warm_start)))
        return SimpleNamespace(solved=True, j_star=1.0)

    monkeypatch.setattr(robustness, "_factory", factory)
    monkeypatch.setattr(robustness.optimum, "solve_episode", solve)
    monkeypatch.setattr("experiments.optimum_table.table_value", lambda *args: None)
    out = tmp_path / "robustness.csv"
    cell = {"episode_duration_s": 2.0, "control_dt_s": 0.05}
    robustness.run("slosh", 1, out, ["slosh-lqr"], models=tmp_path, axes_chosen=["held-out"], env_kwargs=cell)
    warm = [p for p in played if p[0] == "ppo-flight"]
    assert [(dt, k) for _, _, dt, k in warm] == [(0.05, 1.0), (0.05, 2.0), (0.05, 4.0)]
    assert {m for _, m, _, _ in warm} == {str(tmp_path / "models/fs-flight/ppo-flight/seed0/best/model.zip")}
    assert [(e, c["parameters"], c["sensors"], a.shape) for e, c, a in solved] == [
        (robustness.PLANTS["slosh"], k, 0.0, (40, 2)) for k in (1.0, 2.0, 4.0)
    ]
    for _, _, actions in solved:  # full throttle until the episode ended early, then zeros
        ended = int(np.argmin(actions[:, 0]))
        assert 0 < ended < 40 and np.all(actions[:ended] == 1.0) and np.all(actions[ended:] == 0.0)


def test_recorded_curves_leave_out_the_points_not_all_recorded(tmp_path, monkeypatch):
    """``--recorded`` plays and solves nothing: a point whose episodes are not all in the record
    is left out of the rows and named on the page."""
    monkeypatch.setattr(robustness, "j_star", lambda env_id, conditions, seed, kwargs, warm=None: 1.0)
    name, kwargs = SHORT["linear"]
    out = tmp_path / "robustness.csv"
    full = robustness.run("linear", 2, out, [name], env_kwargs=kwargs)
    record = out.with_suffix(".episodes.jsonl")
    lines = record.read_text().splitlines()
    kept = [line for line in lines if not (json.loads(line)["axis"] == "delay" and json.loads(line)["seed"] == 1)]
    record.write_text("\n".join(kept) + "\n")
    monkeypatch.setattr(robustness, "rollout", lambda *a, **k: pytest.fail("a recorded run played an episode"))
    rows = robustness.run("linear", 2, out, [name], env_kwargs=kwargs, recorded=True)
    assert [(r["axis"], r["level"]) for r in rows] == [(r["axis"], r["level"]) for r in full if r["axis"] != "delay"]
    missing = [("delay", float(d)) for d in robustness.DELAY_LEVELS]
    text = robustness.page(rows, "linear", [json.loads(line) for line in kept], missing)
    assert "Not measured yet: delay 0, delay 1, delay 2, delay 3." in text
    assert "--axes" not in text  # the command that resumes it runs every axis, delay included
    empty = tmp_path / "empty" / "robustness.csv"
    assert robustness.run("linear", 2, empty, [name], env_kwargs=kwargs, recorded=True) == []
    assert not empty.parent.exists()  # nothing written


def test_an_episode_whose_optimum_did_not_solve_leaves_its_point_out(tmp_path, monkeypatch):
    def j_star(env_id, conditions, seed, kwargs, warm=None):
        if conditions == {"sensors": 1.0, "delay_steps": 2} and seed == 1:
            raise robustness.UnsolvedOptimum("J* did not solve (Maximum_Iterations_Exceeded after 1000 iterations)")
        return 1.0

    monkeypatch.setattr(robustness, "j_star", j_star)
    name, kwargs = SHORT["linear"]
    out = tmp_path / "robustness.csv"
    rows = robustness.run("linear", 2, out, [name], env_kwargs=kwargs)
    points = [(r["axis"], r["level"]) for r in rows]
    assert ("delay", 2.0) not in points and ("delay", 3.0) in points
    recorded = [json.loads(line) for line in out.with_suffix(".episodes.jsonl").read_text().splitlines()]
    assert not any(r["axis"] == "delay" and r["level"] == 2 and r["seed"] == 1 for r in recorded)


def test_every_committed_record_reads_back_its_rows(tmp_path):
    """Each plant page's record gives its committed rows again without playing or solving."""
    for csv_path in sorted(DOCS.glob("*/robustness.csv")):
        plant = csv_path.parent.name
        out = tmp_path / plant / "robustness.csv"
        out.parent.mkdir()
        shutil.copy(csv_path.with_suffix(".episodes.jsonl"), out.with_suffix(".episodes.jsonl"))
        committed = list(csv.DictReader(csv_path.open()))
        names = list(dict.fromkeys(r["agent"] for r in committed))
        for name in set(names) & set(robustness.learned_agents(plant)):
            _fake_models(tmp_path / plant, robustness.training_entry(plant, name), name)
        rows = robustness.run(plant, int(committed[0]["seeds"]), out, names, models=tmp_path / plant, recorded=True)
        assert [(r["agent"], r["axis"], float(r["level"])) for r in committed] == [
            (r["agent"], r["axis"], r["level"]) for r in rows
        ], plant
        for old, new in zip(committed, rows, strict=True):
            assert float(old["j_over_j_star"]) == pytest.approx(new["j_over_j_star"], rel=1e-12)
