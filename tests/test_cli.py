import os
import subprocess
import sys

import pytest

from experiments import cli


def test_demo_prints_a_table_where_lqr_beats_free_drift(capsys):
    assert cli.main(["demo", "--seeds", "2"]) == 0
    out = capsys.readouterr().out
    rows = {line.split()[0]: float(line.split()[1]) for line in out.splitlines() if line.startswith(("zero", "lqr"))}
    assert set(rows) == {"zero", "lqr-zoh", "lqr-continuous"}
    assert rows["lqr-zoh"] < 0.5 * rows["zero"]
    assert rows["lqr-zoh"] <= rows["lqr-continuous"] * 1.001  # the sampled-data optimum is no worse


def test_bad_preset_is_a_one_line_error_with_exit_code_2():
    proc = subprocess.run([sys.executable, "train.py", "demo", "--preset", "nope"], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "preset must be one of [" in proc.stderr and "'heravi-2017', 'pyramid-4wheel'" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_tune_pid_help_names_the_console_script(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["tune-pid", "--help"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.startswith("usage: attitude-envs tune-pid")


def test_train_py_is_the_same_command_line():
    proc = subprocess.run([sys.executable, "train.py", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("usage: attitude-envs")


def test_unknown_reproduction_is_rejected():
    assert cli.main(["reproduce", "no-such-paper"]) == 2


def test_tune_pid_writes_gains_that_evaluate_loads(tmp_path, capsys):
    gains = tmp_path / "gains.json"
    argv = ["tune-pid", "--env", "attitude_envs/AirBearing-v0", "--population", "4", "--generations", "1"]
    assert cli.main([*argv, "--workers", "1", "--out", str(gains)]) == 0
    assert gains.is_file()
    out = tmp_path / "eval"
    argv = ["evaluate", "--env", "attitude_envs/AirBearing-v0", "--policy", f"pid:gains:{gains}", "--seeds", "1"]
    assert cli.main([*argv, "--workers", "1", "--out", str(out)]) == 0
    assert "pid-gains-" in capsys.readouterr().out
    assert (out / "report.md").is_file()


def test_evaluate_runs_a_scenario_preset_beside_the_healthy_run(tmp_path, capsys):
    argv = ["evaluate", "--policy", "lqr", "--scenario", "wheel-failure", "--seeds", "1", "--workers", "1"]
    assert cli.main([*argv, "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "fault: wheel-failure" in out and "fault: healthy" in out
    assert cli.main(["evaluate", "--policy", "lqr", "--scenario", "no-such", "--out", str(tmp_path)]) == 2


def test_install_puts_no_bare_train_module_on_the_path(tmp_path):
    # train.py is a thin file at the repository root, not an installed module (the package
    # index has a project named "train"); the console script points into experiments.cli.
    code = "import importlib.util as u; print(u.find_spec('train') is None, u.find_spec('experiments.cli') is not None)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert proc.stdout.split() == ["True", "True"], proc.stderr


def test_the_command_line_keeps_jax_programs_in_the_suites_cache(tmp_path, monkeypatch):
    """`attitude-envs` turns on JAX's persistent compilation cache in cache_dir("jax") (for its
    subprocesses too, through the environment), unless the user named a folder or turned it off."""
    jax = pytest.importorskip("jax")
    before = jax.config.jax_compilation_cache_dir
    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path))
    try:
        monkeypatch.setenv("JAX_ENABLE_COMPILATION_CACHE", "false")
        monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
        cli.use_jax_compilation_cache()
        assert "JAX_COMPILATION_CACHE_DIR" not in os.environ
        monkeypatch.delenv("JAX_ENABLE_COMPILATION_CACHE")
        cli.use_jax_compilation_cache()
        assert os.environ["JAX_COMPILATION_CACHE_DIR"] == str(tmp_path / "jax")
        assert jax.config.jax_compilation_cache_dir == str(tmp_path / "jax")
        monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "mine"))
        cli.use_jax_compilation_cache()  # the user's folder wins
        assert os.environ["JAX_COMPILATION_CACHE_DIR"] == str(tmp_path / "mine")
    finally:
        jax.config.update("jax_compilation_cache_dir", before)
