"""The optional SBX (JAX) backend: chosen per run, saves and loads like SB3 models, resumes
exactly, and campaigns and reports name it (training on every env id: test_sb3_native_env)."""

import importlib.util
import json

import numpy as np
import pytest

from experiments.training.algorithm import Algorithm, check_backend

pytest.importorskip("stable_baselines3")

import attitude_envs  # noqa: F401,E402
from experiments.training.hyperparams import split_hyperparams  # noqa: E402
from experiments.training.training import load_trained, train  # noqa: E402

RW = "attitude_envs/ReactionWheel-v0"
LS_SHORT = {"episode_steps": 40, "x0_std": 0.1}
PPO_TINY = {"n_envs": 2, "n_steps": 125, "batch_size": 125, "n_epochs": 1, "policy_kwargs": "dict(net_arch=[16])"}


def test_backend_names_are_checked_with_the_accepted_ones():
    assert check_backend("SBX", "sac") == "sbx" and check_backend("sb3", "recurrentppo") == "sb3"
    with pytest.raises(ValueError, match=r"backend must be one of \['sb3', 'sbx', 'jax'\], got 'tf'"):
        check_backend("tf", "ppo")
    with pytest.raises(ValueError, match="backend 'sbx' implements .* not 'a2c'"):
        check_backend("sbx", "a2c")
    with pytest.raises(ValueError, match="backend must be one of"):
        Algorithm("ppo", "tf")


def test_without_the_extra_sbx_is_a_clear_error_naming_the_install_and_the_fallback(monkeypatch):
    import sys

    from experiments.training.algorithm import algorithm_class

    monkeypatch.setitem(sys.modules, "sbx", None)  # as if not installed
    with pytest.raises(ValueError, match=r"pip install 'attitude-envs\[sbx\]'; or train on PyTorch: --backend sb3"):
        algorithm_class("sac", "sbx")


def test_evaluate_names_an_sbx_model_by_its_algorithm_and_backend(tmp_path):
    from experiments.cli import _algo_label

    for backend, label in (("sbx", "sac-sbx"), ("sb3", "sac")):
        run = tmp_path / backend
        (run / "final").mkdir(parents=True)
        (run / "config.json").write_text(json.dumps({"algo": "sac", "backend": backend}))
        assert _algo_label(run / "final" / "model.zip") == label


needs_sbx = pytest.mark.skipif(
    importlib.util.find_spec("sbx") is None, reason="the optional sbx extra is not installed"
)


@needs_sbx
def test_one_zoo_entry_serves_both_backends():
    entry = {"policy_kwargs": "dict(net_arch=[8], activation_fn=nn.ReLU)", "backend": "sbx"}
    sbx_kwargs = split_hyperparams(entry, 3, Algorithm("ppo", "sbx"))["kwargs"]["policy_kwargs"]
    import flax.linen as fnn

    assert sbx_kwargs == {"net_arch": [8], "activation_fn": fnn.relu, "ortho_init": True}  # SB3's PPO default
    keep = split_hyperparams({**entry, "policy_kwargs": "dict(ortho_init=False)"}, 3, Algorithm("ppo", "sbx"))["kwargs"]
    assert keep["policy_kwargs"] == {"ortho_init": False}
    assert "ortho_init" not in split_hyperparams({**entry}, 3, Algorithm("sac", "sbx"))["kwargs"]["policy_kwargs"]
    import torch.nn as tnn

    assert (
        split_hyperparams({**entry, "backend": "sb3"}, 3, Algorithm("ppo"))["kwargs"]["policy_kwargs"]["activation_fn"]
        is tnn.ReLU
    )
    with pytest.raises(ValueError, match="activation_fn Softsign has no SBX equivalent"):
        split_hyperparams({**entry, "policy_kwargs": "dict(activation_fn=nn.Softsign)"}, 3, Algorithm("ppo", "sbx"))


@needs_sbx
def test_sbx_sac_resumes_a_killed_run_bitwise(tmp_path, monkeypatch):
    options = {
        "env_kwargs": {"episode_duration_s": 5.0},
        "overrides": {"learning_starts": 100, "batch_size": 64, "policy_kwargs": "dict(net_arch=[32, 32])"},
        "total_timesteps": 600,
        "eval_freq": 200,
        "checkpoint_freq": 200,
        "eval_episodes": 2,
        "backend": "sbx",
    }
    reference = train("sac", RW, tmp_path / "reference", **options)
    import experiments.training.training as training

    real = training.write_checkpoint
    calls = {"n": 0}

    def killed_after_the_second(*args, **kwargs):
        real(*args, **kwargs)
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt  # the process dies right after the 400-step checkpoint

    monkeypatch.setattr(training, "write_checkpoint", killed_after_the_second)
    with pytest.raises(KeyboardInterrupt):
        train("sac", RW, tmp_path / "killed", **options)
    monkeypatch.setattr(training, "write_checkpoint", real)
    without_backend = {k: v for k, v in options.items() if k != "backend"}
    resumed = train("sac", RW, tmp_path / "killed", resume=True, **without_backend)  # keeps the run's backend
    assert resumed.resumed_from == 400
    ref_csv = (tmp_path / "reference" / "evaluations.csv").read_text()
    assert (tmp_path / "killed" / "evaluations.csv").read_text() == ref_csv and ref_csv.count("\n") == 5
    obs = np.random.default_rng(0).normal(size=(16, 6)).astype(np.float32)
    same = [load_trained(r.model_path).predict(obs, deterministic=True)[0] for r in (reference, resumed)]
    assert np.array_equal(*same)
    with pytest.raises(
        ValueError, match=r"--resume: backend 'sb3' differs from the run's 'sbx' \(pass --backend sbx\)"
    ):
        train("sac", RW, tmp_path / "killed", resume=True, **{**options, "backend": "sb3"})


@needs_sbx
def test_a_campaign_trains_with_sbx_and_its_report_names_the_backend(tmp_path):
    from experiments.campaign import run_campaign
    from experiments.report.writing import write_campaign_report

    campaign = {
        "name": "sbx-tiny",
        "seeds": 2,
        "optimum": {"solve": False},
        "envs": [{"name": "ls", "id": "attitude_envs/LinearSystem-v0", "kwargs": LS_SHORT}],
        "agents": [
            {"name": "lqr-dare", "policy": "linear-lqr"},
            {
                "name": "ppo-sbx",
                "policy": "sb3",
                "train": {"algo": "ppo", "backend": "sbx", "timesteps": 500, "eval_freq": 250, "overrides": PPO_TINY},
            },
        ],
    }
    result = run_campaign(campaign, tmp_path / "c", workers=1)
    assert {r["agent"] for r in result.rows} == {"lqr-dare", "ppo-sbx"}
    saved = json.loads((tmp_path / "c" / "models" / "ls" / "ppo-sbx" / "seed0" / "config.json").read_text())
    assert saved["backend"] == "sbx"
    report = write_campaign_report(result, video=False).read_text()
    assert "ppo (sbx), 500 steps" in report
