"""Chaos test: SIGKILL a training run and a campaign at several points, rerun the same command,
and compare the bytes with an uninterrupted run (exact resume of training runs and campaigns).

Every run is a process of its own, in its own process group, started as ``python train.py ...``
starts (``experiments.cli.main`` on the same arguments, output to a log): a zygote process imports
the trainer's modules once (torch, SB3, SBX, the envs: 7–10 s a process) and forks each run from
there. The kill points are found by polling the run directory. The chains of killed runs and
their uninterrupted references all run at once (a module fixture), the two tests check the bytes."""

import importlib.util
import json
import os
import signal
import subprocess
import sys
import threading
import time
import zipfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
SBX = importlib.util.find_spec("sbx") is not None

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}
# PPO, rollouts of 2 envs × 250 steps = 500 env steps: evaluations and checkpoints at 500, 1000, 1500, 2000.
TRAIN = "train --algo ppo --env attitude_envs/ReactionWheel-v0 --seed 1 --timesteps 2000 --eval-episodes 2".split()
TRAIN += ["--env-kwargs", "{episode_duration_s: 5.0}", "--checkpoint-freq", "500", "--eval-freq", "500"]
TRAIN += ["--params", "n_envs:2", "n_steps:250", "batch_size:250", "n_epochs:1"]
CAMPAIGN = """
name: chaos
seeds: [0, 1]
envs:
  - name: rw
    id: attitude_envs/ReactionWheel-v0
    kwargs: {episode_duration_s: 20.0}
    faults:
      none: []
      w0-out: [{kind: outage, target: actuator, index: 0, onset_s: 5.0}]
agents:
  - {name: zero, policy: zero}
  - {name: lqr, policy: lqr, params: {discretization: zoh}}
  - name: ppo
    policy: sb3
    train:
      algo: ppo
      timesteps: 1000
      seeds: [0]
      checkpoint_freq: 500
      eval_freq: 500
      env_kwargs: {episode_duration_s: 5.0}
      overrides: {n_envs: 2, n_steps: 250, batch_size: 250, n_epochs: 1}
"""


# Reads requests ``[args, log]`` (one JSON line each) on stdin, forks a run per request and writes
# ``start PID`` (in the order of the requests) and ``exit PID STATUS`` lines on stdout. It forks
# while it is a single thread (importing starts none; checked): no lock is held in the child.
ZYGOTE = r"""
import json, os, select, sys, traceback
import experiments.cli, experiments.training.training, stable_baselines3, torch._dynamo  # noqa: F401
try:
    import sbx  # noqa: F401  (imports jax without starting a backend: no thread yet)
except ImportError:
    pass
if os.path.isdir("/proc/self/task"):
    assert len(os.listdir("/proc/self/task")) == 1, "the zygote must fork as a single thread"


def send(line):
    os.write(1, (line + "\n").encode())


def child(args, log):
    os.setsid()  # its own process group: the kill takes any child with it
    null, out = os.open(os.devnull, os.O_RDONLY), os.open(log, os.O_WRONLY | os.O_APPEND | os.O_CREAT)
    os.dup2(null, 0), os.dup2(out, 1), os.dup2(out, 2)
    sys.argv = ["train.py", *args]
    try:
        code = experiments.cli.main(args)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except BaseException:
        traceback.print_exc()
        code = 1
    sys.stdout.flush(), sys.stderr.flush()
    os._exit(code or 0)


buffer, running, open_ = b"", 0, True
while open_ or running:
    if open_ and select.select([0], [], [], 0.005)[0]:
        chunk = os.read(0, 1 << 16)
        open_, buffer = bool(chunk), buffer + chunk
        while b"\n" in buffer:
            line, buffer = buffer.split(b"\n", 1)
            args, log = json.loads(line)
            pid = os.fork()
            if pid == 0:
                child(args, log)
            running += 1
            send(f"start {pid}")
    elif not open_:
        select.select([], [], [], 0.005)
    while running:
        pid, status = os.waitpid(-1, os.WNOHANG)
        if pid == 0:
            break
        running -= 1
        send(f"exit {pid} {os.waitstatus_to_exitcode(status)}")
"""


class _Zygote:
    """The pytest side of :data:`ZYGOTE`: :meth:`run` starts a run, the returned :class:`_Forked`
    polls and waits for it like a :class:`subprocess.Popen`."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", ZYGOTE], cwd=ROOT, env=ENV, stdin=subprocess.PIPE, stdout=subprocess.PIPE
        )
        self.exits: dict[int, int] = {}
        self.started: list[int] = []
        self.changed = threading.Condition()
        self.request = threading.Lock()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for raw in self.proc.stdout:
            kind, pid, *status = raw.decode().split()
            with self.changed:
                if kind == "start":
                    self.started.append(int(pid))
                else:
                    self.exits[int(pid)] = int(status[0])
                self.changed.notify_all()
        with self.changed:  # the zygote ended: no run reports any more
            self.changed.notify_all()

    def alive(self) -> bool:
        return self.proc.poll() is None

    def run(self, args: list[str], log: Path) -> "_Forked":
        with self.request:
            with self.changed:
                count = len(self.started)
            self.proc.stdin.write((json.dumps([args, str(log)]) + "\n").encode())
            self.proc.stdin.flush()
            with self.changed:
                assert self.changed.wait_for(lambda: len(self.started) > count or not self.alive(), 60), "no start"
                assert len(self.started) > count, "the zygote ended"
                return _Forked(self, self.started[count])

    def close(self) -> None:
        """End the zygote once its runs have ended (kill it if one hangs: a failed chain's)."""
        self.proc.stdin.close()
        try:
            self.proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


class _Forked:
    def __init__(self, zygote: _Zygote, pid: int) -> None:
        self.zygote, self.pid = zygote, pid

    def poll(self) -> int | None:
        with self.zygote.changed:
            return self.zygote.exits.get(self.pid)

    def wait(self, timeout: float | None = None) -> int:
        with self.zygote.changed:
            done = lambda: self.pid in self.zygote.exits or not self.zygote.alive()  # noqa: E731
            if not self.zygote.changed.wait_for(done, timeout):
                raise subprocess.TimeoutExpired("train.py", timeout)
            assert self.pid in self.zygote.exits, "the zygote ended before the run"
            return self.zygote.exits[self.pid]


_ZYGOTE: list[_Zygote] = []  # the chaos fixture's


def _run(args: list[str], log: Path) -> _Forked:
    return _ZYGOTE[0].run(args, log)


def _kill_when(proc: _Forked, ready, delay_s: float = 0.0, timeout_s: float = 120.0) -> bool:
    """SIGKILL ``proc``'s process group once ``ready()`` holds (after ``delay_s``); False if it ended first."""
    deadline = time.monotonic() + timeout_s
    while proc.poll() is None:
        if ready():
            time.sleep(delay_s)
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()
            return True
        assert time.monotonic() < deadline, "the kill point never came"
        time.sleep(0.002)
    return False


def _finish(args: list[str], log: Path) -> str:
    proc = _run(args, log)
    assert proc.wait(timeout=180) == 0, log.read_text()[-3000:]
    return log.read_text()


def _lines(path: Path) -> int:
    try:
        return len(path.read_bytes().splitlines())
    except FileNotFoundError:
        return 0


def _pointer_steps(run: Path) -> int:
    try:
        return json.loads((run / "checkpoints" / "latest.json").read_text())["timesteps"]
    except (FileNotFoundError, json.JSONDecodeError):
        return 0


def _weights(model_zip: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(model_zip) as zf:  # tensors and optimizer states (not "data": it holds times)
        return {name: zf.read(name) for name in zf.namelist() if name.endswith(".pth")}


def _actions(model_zip: Path) -> bytes:
    """The deterministic actions of a saved model on fixed observations (an SBX model keeps its
    parameters in the zip's "data", beside wall times)."""
    from experiments.training.training import load_trained

    obs = np.random.default_rng(0).normal(size=(64, 6)).astype(np.float32)
    return load_trained(model_zip).predict(obs, deterministic=True)[0].tobytes()


def _assert_same_training(run: Path, ref: Path) -> None:
    for name in ("evaluations.csv", "best/best.json", "final/final.json", "checkpoints/latest.json"):
        assert (run / name).read_bytes() == (ref / name).read_bytes(), name
    for snapshot in ("best", "final"):
        assert _weights(run / snapshot / "model.zip") == _weights(ref / snapshot / "model.zip"), snapshot
        assert _actions(run / snapshot / "model.zip") == _actions(ref / snapshot / "model.zip"), snapshot


def _chain(args: list[str], rerun: list[str], log: Path, kills, probe) -> list[tuple[bool, object, str]]:
    """Run ``args`` and SIGKILL it at the first kill point (``(ready, delay_s)``), rerun with
    ``rerun`` and kill it at the next one, and so on; then rerun to the end. Returns, per run,
    whether it was killed, ``probe()`` right after the kill, and the log so far."""
    done = []
    for i, (ready, delay) in enumerate(kills):
        killed = _kill_when(_run(args if i == 0 else rerun, log), ready, delay)
        done.append((killed, probe(), log.read_text()))
    return done + [(False, probe(), _finish(rerun, log))]


def _training_chain(tmp: Path, backend: str = "sb3"):
    """One training run killed four times (each rerun with --resume), beside an uninterrupted one."""
    run, start = tmp / "killed", {}

    def new_eval_row() -> bool:
        """True once an evaluation row appears that was not there when this run started: the kill
        then lands right after the row is fsynced, before (or just as) its checkpoint moves the pointer."""
        rows = _lines(run / "evaluations.csv")
        return rows > start.setdefault("rows", rows)

    kills = [
        (lambda: (run / "config.json").is_file(), 0.0),  # before the first checkpoint
        (lambda: _pointer_steps(run) >= 500, 0.05),  # mid-rollout after a checkpoint
        (new_eval_row, 0.0),
        (lambda: _pointer_steps(run) >= 2000, 0.0),  # after the last checkpoint, before or while final/ is written
    ]
    args = [*TRAIN, "--backend", backend, "--out", str(run)]
    reference = ([*TRAIN, "--backend", backend, "--out", str(tmp / "reference")], tmp / "reference.log")
    return reference, (args, [*args, "--resume"], tmp / "killed.log", kills, lambda: _pointer_steps(run))


MODEL = Path("models") / "rw" / "ppo" / "seed0"  # the campaign's training run


def _campaign_chain(tmp: Path):
    """One campaign killed during training, then (the same command again) during the episodes,
    then run to the end, beside an uninterrupted one."""
    config, out = tmp / "chaos.yml", tmp / "killed"
    config.write_text(CAMPAIGN)
    kills = [
        (lambda: _pointer_steps(out / MODEL) >= 500, 0.05),  # training, mid-rollout after a checkpoint
        (lambda: _lines(out / "episodes.jsonl") >= 2, 0.0),  # episodes
    ]

    def args(directory: Path) -> list[str]:
        return ["benchmark", "--config", str(config), "--out", str(directory), "--workers", "1", "--no-video"]

    def probe() -> tuple[int, int]:
        return _pointer_steps(out / MODEL), _lines(out / "episodes.jsonl")

    return (args(tmp / "reference"), tmp / "reference.log"), (args(out), args(out), tmp / "killed.log", kills, probe)


@pytest.fixture(scope="module")
def chaos(tmp_path_factory) -> dict[str, tuple[Path, list]]:
    """All chains and their references at once (the processes wait on disk and process start-up
    much of the time: more of them than cores keep two cores busy)."""
    names = ["training", "campaign"] + (["training-sbx"] if SBX else [])
    tmp = {name: tmp_path_factory.mktemp(name) for name in names}
    setups = {"training": _training_chain(tmp["training"]), "campaign": _campaign_chain(tmp["campaign"])}
    if SBX:
        setups["training-sbx"] = _training_chain(tmp["training-sbx"], "sbx")
    _ZYGOTE.append(_Zygote())
    try:
        with ThreadPoolExecutor(2 * len(setups)) as pool:
            futures = {
                name: (pool.submit(_finish, *ref), pool.submit(_chain, *chain)) for name, (ref, chain) in setups.items()
            }
            results = {}
            for name, (reference, chain) in futures.items():
                reference.result()
                results[name] = (tmp[name], chain.result())
    finally:
        _ZYGOTE.pop().close()
    return results


@pytest.mark.parametrize("backend", ["sb3", "sbx"])
def test_training_killed_anywhere_resumes_to_the_same_bytes(chaos, backend):
    if backend == "sbx" and not SBX:
        pytest.skip("the optional sbx extra is not installed")
    tmp, results = chaos["training" if backend == "sb3" else "training-sbx"]
    ref, run = tmp / "reference", tmp / "killed"
    rows = (ref / "evaluations.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows] == [
        "timesteps",
        "0",
        "500",
        "1000",
        "1500",
        "2000",
    ]  # the initial policy, then the budget
    killed, steps, logs = zip(*results, strict=True)
    assert all(killed[:3]) and steps[0] == 0 and 0 < steps[1] < 2000 and 0 < steps[2] < 2000, steps
    assert steps[3] == 2000
    for i in (1, 2):  # the next run continued from the checkpoint instead of starting again
        assert f": resuming at {steps[i]} steps (" in logs[i + 1][len(logs[i]) :]
    _assert_same_training(run, ref)
    # Resuming a finished run: one line, exit status 0 (was an AttributeError traceback).
    assert "run already complete at 2000 steps" in logs[4][len(logs[3]) :] and "Traceback" not in logs[4]


def _leaderboards(out: Path) -> str:
    report = (out / "report.md").read_text()
    budget = [line for line in report.splitlines() if line.startswith("| training budget")]
    return "\n".join(budget) + report.split("## Leaderboards")[1].split("## Figures")[0]


def test_campaign_killed_in_training_and_in_episodes_resumes_to_the_same_table(chaos):
    tmp, results = chaos["campaign"]
    ref, out = tmp / "reference", tmp / "killed"
    killed, at_kill, _ = zip(*results, strict=True)
    assert killed[:2] == (True, True), at_kill
    assert 0 < at_kill[0][0] < 1000 and at_kill[0][1] == 0 and 2 <= at_kill[1][1] < 12, at_kill
    assert _lines(ref / "episodes.csv") == 1 + 12
    assert (out / "episodes.csv").read_bytes() == (ref / "episodes.csv").read_bytes()
    assert _leaderboards(out) == _leaderboards(ref) and "best snapshot at" in _leaderboards(ref)
    _assert_same_training(out / MODEL, ref / MODEL)
