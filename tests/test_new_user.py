"""What a new user trips on: wrong policy/env pairings, a model evaluated on another env, output
folders that cannot be made, a missing optional extra, one seeds syntax, one name for the
process count, help with no subcommand, and a training budget that rounds up."""

import importlib
import json
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import attitude_envs
from attitude_envs.registration import CONSTRAINED_ENV_IDS
from experiments import cli
from experiments.policies import POLICIES, build_policy, check_policy_env, policies_for
from experiments.seeds import parse_seeds

ROOT = Path(__file__).resolve().parents[1]


def _one_line_error(capsys, *names: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "Traceback" not in err, err
    for name in names:
        assert name in err, (name, err)
    return err


def test_every_policy_declares_the_envs_it_applies_to():
    names = {e.split("/")[1].split("-v")[0] for e in (*attitude_envs.ENV_IDS, *CONSTRAINED_ENV_IDS)}
    for entry in POLICIES.values():
        envs = entry.envs
        assert envs is None or set(envs) <= names
    assert policies_for("attitude_envs/LinearSystem-v0") == [
        "zero",
        "mpc",
        "linear-lqr",
        "q-learning-lqr",
        "linear-lqr+kf",
        "sb3",
    ]
    assert "slosh-fuzzy" in policies_for("attitude_envs/FuelSlosh-v0")
    assert "lqr" not in policies_for("attitude_envs/Magnetorquer-v0")


def test_a_policy_on_an_env_it_does_not_fit_is_a_one_line_error_listing_those_that_fit(tmp_path, capsys):
    argv = ["evaluate", "--env", "attitude_envs/LinearSystem-v0", "--policy", "slosh-pd", "--out", str(tmp_path)]
    assert cli.main(argv) == 2
    err = _one_line_error(capsys, "'slosh-pd' does not apply to attitude_envs/LinearSystem-v0", "FuelSlosh")
    assert "linear-lqr, q-learning-lqr" in err
    assert not (tmp_path / "episodes.csv").exists()
    with pytest.raises(ValueError, match="policies for Magnetorquer: zero, mpc, amnftsmc"):
        build_policy({"policy": "lqr"}, gym.make("attitude_envs/Magnetorquer-v0"))
    check_policy_env("zero", "attitude_envs/FuelSlosh-v0")  # applies everywhere


def test_out_that_cannot_be_created_is_a_one_line_error(capsys):
    assert cli.main(["evaluate", "--policy", "lqr", "--out", "/proc/attitude-envs-test/x"]) == 2
    _one_line_error(capsys, "--out '/proc/attitude-envs-test/x' cannot be created or written")
    assert not Path("/proc/attitude-envs-test").exists()


def test_checking_out_leaves_no_folder_behind(tmp_path, capsys):
    out = tmp_path / "a" / "b"
    argv = ["evaluate", "--env", "attitude_envs/LinearSystem-v0", "--policy", "slosh-pd", "--out", str(out)]
    assert cli.main(argv) == 2
    assert not (tmp_path / "a").exists()


def test_tune_without_optuna_names_the_extra(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "optuna", None)  # import optuna raises ImportError
    assert cli.main(["tune", "--algo", "ppo", "--out", str(tmp_path)]) == 2
    _one_line_error(capsys, "tune needs the package 'optuna'", "attitude-envs[tune,sb3]")


@pytest.mark.parametrize(
    ("text", "seeds"),
    [("3", [0, 1, 2]), (3, [0, 1, 2]), ("10-12", [10, 11, 12]), ("0,3,7-8", [0, 3, 7, 8]), ([4, 2], [4, 2])],
)
def test_one_seeds_syntax(text, seeds):
    assert parse_seeds(text) == seeds


@pytest.mark.parametrize(
    ("text", "why"),
    [
        (-3, "a count must be >= 1"),
        ("-3", "is not an integer or a range"),
        (0, "a count must be >= 1"),
        ("4-2", "runs backwards"),
        ("1,1", "appears twice"),
        ([], "at least one integer"),
        (True, "a boolean"),
        ("a", "is not an integer"),
    ],
)
def test_bad_seeds_name_the_parameter_and_the_syntax(text, why):
    with pytest.raises(ValueError, match=why) as exc:
        parse_seeds(text, "agents[0].train.seeds")
    assert str(exc.value).startswith("agents[0].train.seeds must be a count N") and "comma list" in str(exc.value)


def test_seeds_mean_the_same_in_evaluate_demo_and_optimum():
    parser = cli.build_parser()
    for argv in (["evaluate", "--out", "x"], ["demo"], ["optimum"]):
        assert parser.parse_args([*argv, "--seeds", "2"]).seeds == [0, 1]
        assert parser.parse_args([*argv, "--seeds", "5-6"]).seeds == [5, 6]
    assert parser.parse_args(["optimum"]).seeds == [0]  # the default: one episode, seed 0
    assert parser.parse_args(["evaluate", "--out", "x"]).seeds == [0, 1, 2, 3, 4]


def test_bad_seeds_on_the_command_line_are_a_one_line_usage_error(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["evaluate", "--out", "x", "--seeds", "4-2"])
    assert exc.value.code == 2
    _one_line_error(capsys, "argument --seeds", "runs backwards")


def test_jobs_is_the_one_name_of_the_process_count():
    parser = cli.build_parser()
    for argv in (["evaluate", "--out", "x"], ["benchmark", "--out", "x"], ["tune", "--algo", "ppo", "--out", "x"]):
        assert parser.parse_args([*argv, "--jobs", "3"]).jobs == 3
        assert parser.parse_args([*argv, "-j", "2"]).jobs == 2
        assert parser.parse_args([*argv, "--workers", "4"]).jobs == 4  # the old name still works
    assert parser.parse_args(["optimum", "--jobs", "2"]).jobs == 2
    assert parser.parse_args(["tune-pid", "--jobs", "1"]).jobs == 1
    for command in ("evaluate", "benchmark", "tune", "optimum", "tune-pid"):
        help_text = parser._subparsers._group_actions[0].choices[command].format_help()
        assert "--jobs" in help_text and "--workers" not in help_text, command


def test_no_subcommand_prints_the_help_and_runs_nothing():
    proc = subprocess.run([sys.executable, "train.py"], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 2
    assert proc.stdout.startswith("usage: attitude-envs") and "benchmark" in proc.stdout and "tune-pid" in proc.stdout
    assert "rest-to-rest" not in proc.stdout  # the demo did not run


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A 100-step PPO budget on ReactionWheel-v0 in rollouts of 64: trains 128 steps."""
    out = tmp_path_factory.mktemp("tiny") / "run"
    argv = ["train", "--algo", "ppo", "--env", "attitude_envs/ReactionWheel-v0", "--out", str(out)]
    argv += ["--env-kwargs", "{episode_duration_s: 2.0, action_frame: body}", "--timesteps", "100"]
    argv += ["--params", "n_envs:1", "n_steps:64", "batch_size:32", "n_epochs:1"]
    argv += ["--eval-freq", "1000", "--checkpoint-freq", "1000", "--eval-episodes", "1"]
    proc = subprocess.run([sys.executable, "train.py", *argv], capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return out, proc


def test_a_budget_that_rounds_up_to_whole_rollouts_says_so(tiny_run):
    out, proc = tiny_run
    assert "note: ppo trains in whole rollouts of 64 env steps (1 envs): a budget of 100 steps trains 128" in (
        proc.stderr
    )
    assert "128 steps" in proc.stdout
    assert json.loads((out / "final" / "final.json").read_text())["timesteps"] == 128


def test_a_model_evaluated_on_another_env_is_a_one_line_error(tiny_run, tmp_path, capsys):
    out, _ = tiny_run
    argv = ["evaluate", "--env", "attitude_envs/AirBearing-v0", "--model", str(out), "--seeds", "1"]
    assert cli.main([*argv, "--jobs", "1", "--out", str(tmp_path)]) == 2
    _one_line_error(capsys, "was trained on attitude_envs/ReactionWheel-v0", "not on attitude_envs/AirBearing-v0")
    argv = ["evaluate", "--env", "attitude_envs/ReactionWheel-v0", "--model", str(out), "--seeds", "1"]
    assert cli.main([*argv, "--jobs", "1", "--out", str(tmp_path / "wheels")]) == 2  # trained on body torques
    _one_line_error(capsys, "was trained for a different env: its action_space")
    argv += ["--env-kwargs", "{episode_duration_s: 2.0, action_frame: body}"]
    assert cli.main([*argv, "--jobs", "1", "--out", str(tmp_path / "same")]) == 0


def test_the_env_layer_imports_nothing_of_training_or_process_management():
    """Importing every module of attitude_envs loads neither the RL libraries nor tqdm, nor a layer above; only
    its ``jax`` subpackage (the JAX-native plants, an optional extra) loads jax, and no RL library either."""
    code = (
        "import importlib, pkgutil, sys, attitude_envs\n"
        "def walk(path, prefix):\n"  # pkgutil.walk_packages would import attitude_envs.jax to recurse into it
        "    for m in pkgutil.iter_modules(path, prefix):\n"
        "        if m.name != 'attitude_envs.jax':\n"
        "            module = importlib.import_module(m.name)\n"
        "            if m.ispkg:\n"
        "                walk(module.__path__, m.name + '.')\n"
        "walk(attitude_envs.__path__, 'attitude_envs.')\n"
        "bad = sorted({n.split('.')[0] for n in sys.modules} & "
        "{'stable_baselines3', 'sbx', 'torch', 'tqdm', 'optuna', 'ray', 'jax', 'flax', 'optax', "
        "'experiments', 'agents', 'baselines'})\n"
        "import attitude_envs.jax\n"
        "for m in pkgutil.walk_packages(attitude_envs.jax.__path__, 'attitude_envs.jax.'):\n"
        "    importlib.import_module(m.name)\n"
        "bad += sorted({n.split('.')[0] for n in sys.modules} & "
        "{'stable_baselines3', 'sbx', 'torch', 'tqdm', 'optuna', 'ray', 'experiments', 'agents', 'baselines'})\n"
        "print(bad)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"
    assert not (ROOT / "attitude_envs" / "progress.py").exists()
    assert not (ROOT / "attitude_envs" / "processes.py").exists()


def test_every_core_dependency_is_used():
    """Each core dependency is imported by the product, or needed by one that is (networkx: scikit-fuzzy's
    control module imports it without declaring it)."""
    import tomllib

    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    modules = {"pyyaml": "yaml", "scikit-fuzzy": "skfuzzy", "pygad": "pygad"}
    sources = "\n".join(
        p.read_text(encoding="utf-8")
        for pkg in ("attitude_envs", "baselines", "agents", "experiments")
        for p in (ROOT / pkg).rglob("*.py")
    )
    for dep in deps:
        name = dep.split(">")[0].split("=")[0].split("<")[0].strip().lower()
        module = modules.get(name, name.replace("-", "_"))
        if name == "networkx":
            assert "import networkx" not in sources
            assert (
                "import networkx"
                in (Path(importlib.import_module("skfuzzy.control").__file__).parent / "rule.py").read_text()
            )
            continue
        assert f"import {module}" in sources or f"from {module}" in sources, dep


def test_env_kwargs_read_exponents_as_numbers_and_name_a_bad_value(tmp_path, capsys):
    from experiments.training.hyperparams import load_yaml

    assert load_yaml("{integrator_dt_s: 1e-3, n: 5E2, s: lin_1e-4, d: 1.0e-3}") == {
        "integrator_dt_s": 0.001,
        "n": 500.0,
        "s": "lin_1e-4",
        "d": 0.001,
    }
    argv = ["evaluate", "--env", "attitude_envs/AirBearing-v0", "--policy", "zero", "--seeds", "1", "--jobs", "1"]
    assert cli.main([*argv, "--env-kwargs", "{control_dt_s: fast}", "--out", str(tmp_path / "a")]) == 2
    _one_line_error(capsys, "control_dt_s must be a number", "'fast'")
    kwargs = "{control_dt_s: 1e-1, episode_duration_s: 1}"
    assert cli.main([*argv, "--env-kwargs", kwargs, "--out", str(tmp_path / "b")]) == 0


@pytest.mark.parametrize(
    ("env_id", "switch"),
    [
        ("attitude_envs/Magnetorquer-v0", "observe_field"),
        ("attitude_envs/Magnetorquer-v0", "gravity_gradient"),
        ("attitude_envs/FuelSlosh-v0", "observe_slosh"),
        ("attitude_envs/ReactionWheel-v0", "observe_wheel_speeds"),
        ("attitude_envs/AirBearing-v0", "fault_hint"),
    ],
)
def test_a_switch_given_as_a_string_is_refused_not_read_as_true(env_id, switch):
    with pytest.raises(ValueError, match=f"{switch} must be True or False, got 'false'"):
        gym.make(env_id, **{switch: "false"})
    assert getattr(gym.make(env_id, **{switch: True}).unwrapped, switch) is True


def test_a_campaign_pairing_a_policy_with_an_env_it_does_not_fit_fails_at_load():
    from experiments.campaign import PRESETS, load_campaign

    for name in PRESETS:  # every shipped campaign pairs its policies with envs they fit
        load_campaign(name)
    config = {
        "name": "x",
        "envs": [{"name": "ls", "id": "attitude_envs/LinearSystem-v0"}],
        "agents": [{"name": "slosh", "policy": "slosh-pd"}],
    }
    with pytest.raises(ValueError, match=r"agents\[0\] \(slosh\) on env 'ls': policy 'slosh-pd' does not apply"):
        load_campaign(config)


def test_the_fault_campaign_takes_the_same_seeds(capsys):
    from experiments import fault_campaign

    assert fault_campaign.main(["scenario", "wheel-failure", "--seeds", "4-4"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| 4 |")]
    assert len(rows) == 1
    with pytest.raises(SystemExit):
        fault_campaign.main(["scenario", "wheel-failure", "--seeds", "0"])
    assert "argument --seeds: must be a count N" in capsys.readouterr().err


def test_evaluate_can_skip_j_star_solves():
    args = cli.build_parser().parse_args(["evaluate", "--out", "x", "--no-solve"])
    assert args.no_solve is True
    assert cli.build_parser().parse_args(["evaluate", "--out", "x"]).no_solve is False
