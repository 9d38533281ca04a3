"""experiments.processes.run_in_child: a function run in a fresh interpreter, spec and result as JSON."""

import os

import pytest

from experiments.processes import run_in_child

CHILD = """
import os


def report(spec):
    return {"pid": os.getpid(), "spec": spec, "mark": os.environ.get("MARK"),
            "cpus": sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None}


def fail(spec):
    print("some progress", flush=True)
    raise ValueError("boom: " + spec["why"])
"""


@pytest.fixture
def child_module(tmp_path):
    (tmp_path / "childmod.py").write_text(CHILD, encoding="utf-8")
    return tmp_path


def test_the_target_runs_in_a_fresh_interpreter_with_the_spec_and_env_given(child_module):
    spec = {"n": 3, "nested": {"values": [1.5, None, "x"]}}
    env = {**os.environ, "MARK": "set by the parent"}
    result = run_in_child("childmod:report", spec, env=env, cwd=child_module)
    assert result["pid"] != os.getpid() and result["spec"] == spec and result["mark"] == "set by the parent"
    assert result["process_wall_s"] > 0


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no CPU affinity call on this platform")
def test_the_child_runs_on_the_cpus_given_else_on_this_process_s(child_module):
    mine = sorted(os.sched_getaffinity(0))
    assert run_in_child("childmod:report", {}, cwd=child_module)["cpus"] == mine
    assert run_in_child("childmod:report", {}, cpus={mine[-1]}, cwd=child_module)["cpus"] == [mine[-1]]


def test_a_failing_child_is_a_runtime_error_with_its_stderr(child_module):
    with pytest.raises(RuntimeError, match=r"(?s)child childmod:fail failed \(exit 1\).*ValueError: boom: on purpose"):
        run_in_child("childmod:fail", {"why": "on purpose"}, cwd=child_module)


def test_a_child_that_exits_without_a_result_is_a_runtime_error(child_module):
    (child_module / "quiet.py").write_text("def nothing(spec):\n    raise SystemExit(0)\n", encoding="utf-8")
    with pytest.raises(RuntimeError, match=r"child quiet:nothing failed \(exit 0\)"):
        run_in_child("quiet:nothing", {}, cwd=child_module, timeout=120)
