"""The inputs a new user tried that hung, gave a traceback, were silently
accepted or got a vague message. Each now gives one clear line (a ``ValueError`` naming the
parameter and what is accepted) or works."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import attitude_envs
from attitude_envs.registration import LEARNING_TASKS

ALL_IDS = (*attitude_envs.ENV_IDS, *LEARNING_TASKS)


# ---------------------------------------------------------------- envs (tracebacks)
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_reset_options_not_a_mapping_names_options(env_id):
    env = gym.make(env_id)
    with pytest.raises(ValueError, match=r"reset options must be a mapping \(dict\) or None, got 'x'"):
        env.reset(options="x")
    env.close()


def test_vector_reset_options_not_a_mapping():
    envs = gym.make_vec("attitude_envs/LinearSystem-v0", num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="reset options must be a mapping"):
        envs.reset(options=[1, 2])


def test_v0_make_is_quiet_outside_pytest():
    """Gymnasium warns on every -v0 id ("out of date, consider upgrading to v1"); the -v0 ids
    are the papers' problems, kept on purpose: importing the suite silences that warning for
    its own ids only (pytest resets the filters, hence a fresh interpreter)."""
    code = (
        "import warnings, gymnasium as gym, attitude_envs\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    gym.make('attitude_envs/ReactionWheel-v0')\n"
        "    gym.make('attitude_envs/LinearSystem-v0')\n"
        "print([str(x.message) for x in w])\n"
    )
    out = subprocess.run(
        [sys.executable, "-W", "always::DeprecationWarning", "-c", code], capture_output=True, text=True, check=True
    )
    assert "out of date" not in out.stdout + out.stderr
    assert out.stdout.strip() == "[]"


def test_the_filter_matches_only_this_suites_v0_ids():
    import re

    from attitude_envs.registration import OUT_OF_DATE

    ours = "\x1b[33mWARN: The environment attitude_envs/AirBearing-v0 is out of date. You should consider upgrading to version `v1`.\x1b[0m"
    other = ours.replace("attitude_envs/AirBearing-v0", "CartPole-v0")
    assert re.match(OUT_OF_DATE, ours) and not re.match(OUT_OF_DATE, other)


def test_docs_say_ten_ids():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    for page in ("README.md", "docs/getting-started.md"):
        text = (root / page).read_text(encoding="utf-8")
        assert "registers the five ids" not in text and "registers the ten ids" in text, page
    assert len(ALL_IDS) == 10


# ---------------------------------------------------------------- JAX envs
JAX_IDS = ("ReactionWheel-v1", "AirBearing-v1", "LinearSystem-v1", "FuelSlosh-v1", "Magnetorquer-v1")


@pytest.mark.parametrize("value", [None, 3, ("AirBearing-v1",)])
def test_jax_make_not_a_string(value):
    pytest.importorskip("jax")
    from attitude_envs.jax import make

    with pytest.raises(ValueError, match=r"env_id must be a string, one of the suite's ids"):
        make(value)


@pytest.fixture(scope="module")
def air_bearing_jax():
    pytest.importorskip("jax")
    import jax

    from attitude_envs.jax import make

    env, params = make("AirBearing-v1")
    key = jax.random.PRNGKey(0)
    _, state = env.reset(key, params)
    return env, params, key, state


@pytest.mark.parametrize("shape", [(), (1, 3), (4,), (2,)])
def test_jax_step_action_shape_named(air_bearing_jax, shape):
    import jax
    import jax.numpy as jnp

    env, params, key, state = air_bearing_jax
    action = jnp.zeros(shape)
    with pytest.raises(ValueError, match=rf"action must have shape \(3,\) .*got shape {re.escape(str(shape))}"):
        env.step(key, state, action, params)
    with pytest.raises(ValueError, match="action must have shape"):  # inside jit: raised at trace time
        jax.jit(env.step)(key, state, action, params)


def test_jax_step_another_plants_params(air_bearing_jax):
    from attitude_envs.jax import make

    env, _, key, state = air_bearing_jax
    _, linear_params = make("LinearSystem-v1")
    with pytest.raises(ValueError, match=r"params must be AirBearing's .*EnvParams.*got .*linear_system\.EnvParams"):
        env.step(key, state, np.zeros(3), linear_params)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_jax_step_nonfinite_action_ends_the_episode_flagged(air_bearing_jax, bad):
    """A NaN action cannot raise under jit: the step ends the episode (terminated, reward
    NaN, ``info["invalid_action"]``) and the autoreset starts afresh, so no NaN state carries on."""
    import jax.numpy as jnp

    env, params, key, state = air_bearing_jax
    obs, new_state, reward, terminated, truncated, info = env.step(key, state, jnp.array([0.1, bad, 0.0]), params)
    assert bool(terminated) and bool(info["invalid_action"]) and not bool(truncated)
    assert int(new_state.time) == 0 and bool(jnp.all(jnp.isfinite(obs)))
    ok = env.step(key, state, jnp.array([0.1, 0.2, 0.0]), params)
    assert not bool(ok[5]["invalid_action"]) and not bool(ok[3]) and np.isfinite(float(ok[2]))


@pytest.mark.parametrize("name", JAX_IDS)
def test_jax_state_from_takes_the_wrapped_env(name):
    pytest.importorskip("jax")
    import jax

    from attitude_envs.jax import make

    env, _ = make(name)
    wrapped = gym.make(f"attitude_envs/{name}")
    wrapped.reset(seed=3)
    a = env.state_from(wrapped)
    b = env.state_from(wrapped.unwrapped)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


# ---------------------------------------------------------------- command line
from experiments import cli  # noqa: E402


def _one_line(capsys, argv: list[str], *needles: str) -> str:
    """``argv`` exits 2 with one line on stderr, no traceback, holding every needle."""
    with pytest.raises(SystemExit) as raised:  # argparse's errors exit; ours return 2
        raise SystemExit(cli.main(argv))
    assert raised.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, (needle, err)
    return err


# hangs
def test_tune_with_a_bad_fixed_override_fails_once_before_any_trial(tmp_path, capsys):
    pytest.importorskip("optuna")
    out = tmp_path / "study"
    argv = ["tune", "--algo", "ppo", "--env", "attitude_envs/AirBearing-v1", "--backend", "sb3", "--out", str(out)]
    _one_line(capsys, [*argv, "--params", "gamma:abc", "--trials", "2", "--timesteps", "200"], "gamma", "(0, 1]")
    assert not list(out.glob("trial-*"))


def test_a_study_whose_trials_all_fail_stops(tmp_path, monkeypatch):
    """A drawn setting that fails is redrawn; when every trial fails the search stops with one error."""
    pytest.importorskip("optuna")
    from experiments.training import tuning

    def failing(*args, **kwargs):
        raise ValueError("cannot train this")

    monkeypatch.setattr(tuning, "train", failing)
    with pytest.raises(ValueError, match="3 trials failed"):
        tuning.tune("ppo", "attitude_envs/AirBearing-v1", tmp_path, n_trials=3, timesteps=100, backend="sb3")


@pytest.mark.parametrize("seeds", ["100000000", "999999999999999999999", "0-100000"])
def test_evaluate_refuses_a_huge_seed_list_at_once(tmp_path, capsys, seeds):
    argv = ["evaluate", "--policy", "lqr", "--seeds", seeds, "--no-solve", "--out", str(tmp_path / "e")]
    _one_line(capsys, argv, "--seeds", "at most 100000")
    assert not (tmp_path / "e").exists()


def test_evaluate_seed_offset_beyond_the_largest_seed(tmp_path, capsys):
    argv = ["evaluate", "--policy", "lqr", "--seeds", "5", "--seed-offset", "2147483646", "--out", str(tmp_path)]
    _one_line(capsys, argv, "--seed-offset", "2147483647")


def test_evaluate_help_states_the_seed_limits(capsys):
    with pytest.raises(SystemExit):
        cli.main(["evaluate", "--help"])
    assert "at most 100000" in " ".join(capsys.readouterr().out.split())


# tracebacks
@pytest.mark.parametrize("command", ["tune", "optimum"])
def test_unwritable_out(tmp_path, capsys, command):
    taken = tmp_path / "file"
    taken.write_text("x")
    argv = {
        "tune": ["tune", "--algo", "ppo", "--backend", "sb3"],
        "optimum": ["optimum", "--seeds", "1"],
    }[command]
    _one_line(capsys, [*argv, "--out", str(taken / "sub")], "--out", "is an existing file")


def test_tune_unknown_env(tmp_path, capsys):
    pytest.importorskip("optuna")
    argv = ["tune", "--algo", "ppo", "--env", "attitude_envs/Nope-v1", "--backend", "sb3", "--out", str(tmp_path)]
    _one_line(capsys, argv, "unknown env id 'attitude_envs/Nope-v1'")


@pytest.mark.parametrize("env_id", ["FuelSlosh-v0", "LinearSystem-v1", "Magnetorquer-v0"])
def test_tune_pid_on_a_plant_without_a_pid(tmp_path, capsys, env_id):
    argv = ["tune-pid", "--env", f"attitude_envs/{env_id}", "--out", str(tmp_path / "g.json")]
    _one_line(capsys, argv, "--env must be one of attitude_envs/ReactionWheel-v0")


def test_tune_pid_help_lists_only_its_ids(capsys):
    with pytest.raises(SystemExit):
        cli.main(["tune-pid", "--help"])
    text = capsys.readouterr().out
    assert "AirBearing-v1" in text and "FuelSlosh" not in text and "LinearSystem" not in text


def test_ray_unreachable_is_one_line(tmp_path, capsys, monkeypatch):
    ray = pytest.importorskip("ray")

    def unreachable(*args, **kwargs):
        raise ConnectionError("Failed to connect to Ray cluster at 10.255.255.1:6379")

    monkeypatch.setattr(ray, "init", unreachable)
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    argv = [
        "evaluate",
        "--policy",
        "lqr",
        "--seeds",
        "1",
        "--no-solve",
        "--out",
        str(tmp_path),
        "--ray",
        "10.255.255.1:6379",
    ]
    _one_line(capsys, argv, "--ray '10.255.255.1:6379'", "ray start --head")


# silently accepted
@pytest.mark.parametrize(
    ("param", "accepted"), [("gamma:1.5", "(0, 1]"), ("learning_rate:-1", "(0, inf)"), ("n_steps:0", ">= 1")]
)
def test_train_refuses_a_hyperparameter_out_of_range(tmp_path, capsys, param, accepted):
    argv = [
        "train",
        "--algo",
        "ppo",
        "--env",
        "attitude_envs/AirBearing-v1",
        "--backend",
        "sb3",
        "--out",
        str(tmp_path),
    ]
    _one_line(
        capsys, [*argv, "--params", param, "--timesteps", "10"], f"hyperparameter {param.split(':')[0]}", accepted
    )
    assert not (tmp_path / "config.json").exists()


@pytest.mark.parametrize("override", [{"gamma": 1.5}, {"learning_rate": -1}, {"learning_rate": "lin_-3e-4"}])
def test_campaign_overrides_are_checked_at_load(override):
    from experiments.campaign import load_campaign

    key = next(iter(override))
    config = {
        "name": "c",
        "seeds": 1,
        "envs": [{"name": "ab", "id": "attitude_envs/AirBearing-v0"}],
        "agents": [
            {
                "name": "ppo",
                "policy": "sb3",
                "env_id": "attitude_envs/AirBearing-v1",
                "train": {"algo": "ppo", "overrides": override},
            }
        ],
    }
    with pytest.raises(ValueError, match=rf"hyperparameter {key} must be in"):
        load_campaign(config)


@pytest.mark.parametrize("command", ["train", "evaluate", "optimum", "tune", "tune-pid"])
def test_empty_out_is_refused(tmp_path, capsys, monkeypatch, command):
    monkeypatch.chdir(tmp_path)
    argv = {
        "train": ["train", "--algo", "ppo"],
        "evaluate": ["evaluate", "--policy", "lqr"],
        "optimum": ["optimum"],
        "tune": ["tune", "--algo", "ppo", "--backend", "sb3"],
        "tune-pid": ["tune-pid"],
    }[command]
    _one_line(capsys, [*argv, "--out", ""], "--out must name")
    assert list(tmp_path.iterdir()) == []


def test_optimum_write_table_out_writes_into_out(tmp_path, capsys, monkeypatch):
    from experiments import optimum_table

    shipped = optimum_table.shipped_table_path()
    before = shipped.stat().st_mtime_ns
    seen = {}

    def write_table(specs, path, executor, **kwargs):
        seen["path"] = Path(path)
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(json.dumps({"entries": []}))
        return Path(path), []

    monkeypatch.setattr(optimum_table, "write_table", write_table)
    assert cli.main(["optimum", "--write-table", "--campaign", "linear", "--out", str(tmp_path / "t"), "-j", "1"]) == 0
    assert seen["path"] == tmp_path / "t" / "optimum_table.json"
    assert shipped.stat().st_mtime_ns == before


def test_evaluate_select_final_on_a_best_snapshot(tmp_path, capsys):
    run = tmp_path / "run"
    for snap in ("best", "final"):
        (run / snap).mkdir(parents=True)
        (run / snap / "model.zip").write_bytes(b"")
    argv = ["evaluate", "--model", str(run / "best"), "--select", "final", "--out", str(tmp_path / "e")]
    _one_line(capsys, argv, "--select final", "the run's 'best' snapshot itself", str(run / "final"))


def test_tune_pid_negative_maneuvers(tmp_path, capsys):
    _one_line(capsys, ["tune-pid", "--maneuvers", "-1", "--out", str(tmp_path / "g.json")], "--maneuvers", ">= 0")


# vague messages
def test_optimum_campaign_unknown_names_campaign(capsys):
    err = _one_line(capsys, ["optimum", "--write-table", "--campaign", "nope:xx"], "--campaign 'nope:xx'")
    assert "--config" not in err


def test_evaluate_scenario_of_another_env(tmp_path, capsys):
    argv = ["evaluate", "--env", "attitude_envs/AirBearing-v0", "--scenario", "wheel-failure", "--policy", "lqr"]
    err = _one_line(capsys, [*argv, "--out", str(tmp_path)], "--scenario wheel-failure is a scenario of")
    assert "preset" not in err


def test_corrupt_checkpoint_pointer_names_the_file(tmp_path):
    from experiments.training.run_dir import latest_checkpoint

    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "checkpoints" / "latest.json").write_text('{"a":')
    with pytest.raises(ValueError, match=r"checkpoint pointer .*latest\.json' is not valid JSON"):
        latest_checkpoint(tmp_path)


# ---------------------------------------------------------------- a tiny trained model
@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A PPO run on AirBearing-v1 of 200 steps (SB3): a run directory with best/ and final/."""
    pytest.importorskip("stable_baselines3")
    from experiments.training.training import train

    out = tmp_path_factory.mktemp("tiny") / "run"
    train(
        "ppo",
        "attitude_envs/AirBearing-v1",
        out,
        total_timesteps=200,
        overrides={"n_envs": 1, "n_steps": 100, "batch_size": 50, "backend": "sb3"},
        checkpoint_freq=100,
        eval_freq=200,
        eval_episodes=1,
        progress=False,
    )
    return out


def _broken_copy(tiny_run: Path, tmp_path: Path) -> Path:
    import shutil

    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    return run


def test_truncated_model_zip_names_the_file(tiny_run, tmp_path):
    from experiments.training.training import load_trained

    run = _broken_copy(tiny_run, tmp_path)
    model = run / "final" / "model.zip"
    model.write_bytes(model.read_bytes()[:3000])
    with pytest.raises(ValueError, match=r"model file .*final/model\.zip' cannot be loaded"):
        load_trained(model, gym.make("attitude_envs/AirBearing-v1"))


def test_truncated_vecnormalize_names_the_file(tiny_run, tmp_path):
    from experiments.training.training import load_trained

    run = _broken_copy(tiny_run, tmp_path)
    stats = run / "final" / "vecnormalize.pkl"
    if not stats.is_file():
        pytest.skip("the AirBearing-v1 recipe does not normalize")
    stats.write_bytes(stats.read_bytes()[:100])
    with pytest.raises(ValueError, match=r"normalization statistics .*vecnormalize\.pkl' cannot be loaded"):
        load_trained(run / "final" / "model.zip", gym.make("attitude_envs/AirBearing-v1"))


def test_corrupt_config_json_names_the_file(tiny_run, tmp_path):
    from experiments.training.training import load_trained

    run = _broken_copy(tiny_run, tmp_path)
    (run / "config.json").write_text('{"algo": "pp')
    with pytest.raises(ValueError, match=r"the run's config .*config\.json' is not valid JSON"):
        load_trained(run / "final" / "model.zip", gym.make("attitude_envs/AirBearing-v1"))


# ---------------------------------------------------------------- item 7: evaluate a -v1 model → J / J*
def test_evaluate_a_v1_model_scores_against_its_v0_cells_j_star(tiny_run, tmp_path, capsys):
    """``evaluate --env AirBearing-v1`` plays the air-bearing campaign's cell ab/none (AirBearing-v0,
    preset air-bearing-85kg) on the learning task, and takes that cell's J* from the shipped
    table: the J* of each episode is the campaign's, and J / J* is printed."""
    import csv

    from experiments.campaign import episode_jobs, load_campaign
    from experiments.optimum_table import episode_specs, load_table

    out = tmp_path / "eval"
    argv = ["evaluate", "--env", "attitude_envs/AirBearing-v1", "--model", str(tiny_run), "--policy", "zero"]
    assert cli.main([*argv, "--seeds", "2", "--no-solve", "--out", str(out), "-j", "1"]) == 0
    printed = capsys.readouterr().out
    assert "plays the air-bearing campaign's cell ab/none" in printed
    campaign = load_campaign("air-bearing")
    table = load_table()
    expected = {}
    for spec in episode_specs(episode_jobs(campaign, tmp_path / "unused")):
        if spec["seed"] < 2 and ["ab", "regulation", "none", spec["seed"]] in spec["cells"]:
            expected[spec["seed"]] = table[spec["hash"]]["j_star"]
    assert sorted(expected) == [0, 1]
    with open(out / "episodes.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["agent"] for r in rows} >= {"ppo", "zero"}
    assert {(r["env"], r["scenario"], r["fault"]) for r in rows} == {("ab", "regulation", "none")}  # the cell's own
    for r in rows:
        assert float(r["j_star"]) == pytest.approx(expected[int(r["seed"])], rel=1e-12)
    board = [line for line in printed.splitlines() if line.startswith("| ") and "ppo" in line]
    assert board and "—" not in board[0].split("|")[7]  # the J / J* column is filled


# ---------------------------------------------------------------- misleading guidance: the first ETA
def test_progress_eta_waits_for_a_first_item_and_leaves_the_start_up_out(monkeypatch):
    """A campaign whose first item took 100 s of start-up (workers, compilation) and then one
    item per 10 s: no ETA before the first item, then 8 items × 10 s (not the 7:20 that the
    rate since the start would give)."""
    import io

    from experiments import progress

    clock = [0.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: clock[0])
    bar = progress.Progress(10, "campaign episodes", "episode", stream=io.StringIO(), bar=False, interval_s=1e9)
    assert bar.status().endswith("ETA ?")
    clock[0] = 100.0
    bar.update()
    assert bar.status().endswith("ETA ?")
    clock[0] = 110.0
    bar.update()
    assert bar.status().endswith("ETA 1:20")


def test_progress_bar_eta_is_measured_from_the_first_item():
    """The same on a terminal (a tqdm bar): ``?`` until an item after the first is done, then
    the rate since the first (tqdm alone would give 109 × 100 s ≈ 3 h after the first item)."""
    import io

    from experiments import progress

    clock = [0.0]
    stream = io.StringIO()
    bar = progress.Progress(10, "campaign episodes", "episode", stream=stream, bar=True)
    bar._bar._time = lambda: clock[0]
    bar._bar.start_t = bar._bar.last_print_t = 0.0
    clock[0] = 100.0
    bar.update()
    assert "<?" in str(bar._bar)
    clock[0] = 110.0
    bar.update()
    assert "<01:20" in str(bar._bar), str(bar._bar)
    bar.close()


@pytest.mark.parametrize(
    ("v1", "kwargs", "campaign", "cell", "fault"),
    [
        ("ReactionWheel-v1", {"action_frame": "body"}, "wheel", "rw", "none"),
        ("AirBearing-v1", {}, "air-bearing", "ab", "none"),
        ("LinearSystem-v1", {}, "linear", "ls", "none"),
        ("FuelSlosh-v1", {}, "slosh", "fs", "none"),
        ("Magnetorquer-v1", {}, "magnetorquer", "mt", "none"),
        (
            "AirBearing-v1",
            {"faults": [{"kind": "outage", "target": "actuator", "index": 2, "onset_s": 2.0}]},
            "air-bearing",
            "ab",
            "yaw-wheel-outage-2s",
        ),
    ],
)
def test_a_learning_task_maps_to_its_plant_campaigns_cell(v1, kwargs, campaign, cell, fault):
    from experiments.campaign import load_campaign

    spec, note = cli.learning_task_cell(f"attitude_envs/{v1}", kwargs, {"none": []}, None)
    (expected,) = [e for e in load_campaign(campaign).envs if e.name == cell]
    assert spec["id"] == expected.id and spec["kwargs"] == expected.kwargs and list(spec["faults"]) == [fault]
    assert spec["scenarios"] == expected.scenarios and f"the {campaign} campaign's cell {cell}/{fault}" in note


def test_a_learning_task_off_the_campaigns_plays_its_v0_episodes():
    spec, note = cli.learning_task_cell("attitude_envs/FuelSlosh-v1", {"episode_duration_s": 50.0}, {"none": []}, None)
    assert spec["id"] == "attitude_envs/FuelSlosh-v0" and "no plant campaign's cell" in note
    assert spec["kwargs"] == {"episode_duration_s": 50.0, "randomize_initial_state": True}  # task keywords left out
