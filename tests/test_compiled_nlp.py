"""baselines.compiled_nlp: a compiled CasADi solver equals the interpreted one, is built once and
then loaded from the cache, leaves no files in the working directory, and says what it needs."""

from __future__ import annotations

import numpy as np
import pytest

casadi = pytest.importorskip("casadi")

from baselines import compiled_nlp  # noqa: E402

needs_compiler = pytest.mark.skipif(compiled_nlp.c_compiler() is None, reason="no C compiler on PATH")

QUIET_SQP = {
    "print_time": False,
    "print_header": False,
    "print_iteration": False,
    "print_status": False,
    "qpsol": "qrqp",
    "qpsol_options": {"print_iter": False, "print_header": False},
}


def _nlp():
    """Rosenbrock's valley with a parameter and a disc constraint (its optimum moves with p)."""
    x, p = casadi.SX.sym("x", 2), casadi.SX.sym("p")
    f = (p - x[0]) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2
    return {"x": x, "p": p, "f": f, "g": casadi.sumsqr(x)}


ARGS = {"x0": [0.5, 0.5], "p": 0.9, "lbg": 0.0, "ubg": 1.5}


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("ATTITUDE_ENVS_CACHE", str(tmp_path / "cache"))
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    return tmp_path


@needs_compiler
def test_compiled_solver_equals_interpreted_and_is_built_once(cache, monkeypatch):
    interpreted = casadi.nlpsol("toy", "sqpmethod", _nlp(), QUIET_SQP)
    reference = interpreted(**ARGS)
    flags = ("-O0",)
    solver = compiled_nlp.compiled_nlpsol("toy", "sqpmethod", _nlp(), QUIET_SQP, flags)
    sol = solver(**ARGS)
    assert solver.stats()["success"]
    np.testing.assert_allclose(np.asarray(sol["x"]), np.asarray(reference["x"]), rtol=0, atol=1e-12)
    (stored,) = (cache / "cache" / "casadi").glob("toy-*.casadi")
    assert [p.suffix for p in stored.with_suffix(".build").iterdir()] == [".so"]
    assert list((cache / "work").iterdir()) == []  # CasADi's sources do not stay in the working directory

    def no_build(*args, **kwargs):
        raise AssertionError("built again instead of loaded from the cache")

    monkeypatch.setattr(compiled_nlp.casadi, "nlpsol", no_build)
    again = compiled_nlp.compiled_nlpsol("toy", "sqpmethod", _nlp(), QUIET_SQP, flags)
    np.testing.assert_array_equal(np.asarray(again(**ARGS)["x"]), np.asarray(sol["x"]))
    assert list((cache / "work").iterdir()) == []
    assert [p.suffix for p in stored.with_suffix(".build").iterdir()] == [".so"]
    # another NLP, other options or other flags are other solvers
    key = compiled_nlp.solver_key("toy", "sqpmethod", _nlp(), QUIET_SQP, flags)
    assert compiled_nlp.solver_key("toy", "sqpmethod", _nlp(), QUIET_SQP, ("-O1",)) != key
    assert compiled_nlp.solver_key("toy", "sqpmethod", _nlp(), {**QUIET_SQP, "max_iter": 3}, flags) != key
    nlp = _nlp()
    other = nlp | {"g": casadi.sumsqr(nlp["x"]) + 1}
    assert compiled_nlp.solver_key("toy", "sqpmethod", other, QUIET_SQP, flags) != key


@needs_compiler
def test_unreadable_cache_entry_is_built_again(cache):
    solver = compiled_nlp.compiled_nlpsol("toy", "sqpmethod", _nlp(), QUIET_SQP, ("-O0",))
    (stored,) = (cache / "cache" / "casadi").glob("toy-*.casadi")
    stored.write_bytes(b"truncated")
    rebuilt = compiled_nlp.compiled_nlpsol("toy", "sqpmethod", _nlp(), QUIET_SQP, ("-O0",))
    np.testing.assert_array_equal(np.asarray(rebuilt(**ARGS)["x"]), np.asarray(solver(**ARGS)["x"]))


def test_no_compiler_is_a_clear_error(cache, monkeypatch):
    monkeypatch.setattr(compiled_nlp.shutil, "which", lambda name: None)
    with pytest.raises(ValueError, match=r"compiled=True needs a C compiler \(gcc or cc\) on PATH"):
        compiled_nlp.compiled_nlpsol("toy", "sqpmethod", _nlp(), QUIET_SQP)
