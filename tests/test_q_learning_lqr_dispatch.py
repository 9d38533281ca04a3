"""Q-learning LQR dispatch: each option name builds its strategy object, learning runs through
the strategies it built, and an unknown name is a ValueError listing the accepted ones."""

from __future__ import annotations

import numpy as np
import pytest
from qlqr_systems import benchmark_systems, linear_env

from agents import QLearningLQR
from agents.qlqr import agent as agent_module
from agents.qlqr.estimators import BatchLeastSquares, RecursiveLeastSquares
from agents.qlqr.evaluation import LSTDQ, BellmanResidualOLS, FeasibleGLSLSTDQ, MatrixBellman
from agents.qlqr.policy_iteration import PolicyIteration
from agents.qlqr.stabilizers import DiscountAnnealing, ValueIterationWarmup
from agents.qlqr.value_iteration import ValueIteration

SYSTEM = benchmark_systems()["kiumarsi2x1"]
# method -> (strategy class, reuses one batch by default)
METHODS = {
    "value_iteration": (ValueIteration, True),
    "policy_iteration": (PolicyIteration, False),
    "lspi": (PolicyIteration, True),
}
ESTIMATORS = {"batch": BatchLeastSquares, "rls": RecursiveLeastSquares}
TD_ESTIMATORS = {
    "lstd": LSTDQ,
    "lstd_gls": FeasibleGLSLSTDQ,
    "ols": BellmanResidualOLS,
    "matrix_bellman": MatrixBellman,
}
STABILIZERS = {"discount_annealing": DiscountAnnealing, "value_iteration": ValueIterationWarmup}


def test_the_dispatch_tables_accept_exactly_the_documented_names():
    assert set(agent_module.METHODS) == set(METHODS)
    assert set(agent_module.ESTIMATORS) == set(ESTIMATORS)
    assert set(agent_module.TD_ESTIMATORS) == set(TD_ESTIMATORS)
    assert set(agent_module.STABILIZERS) == set(STABILIZERS)


@pytest.mark.parametrize("td_estimator", sorted(TD_ESTIMATORS))
@pytest.mark.parametrize("estimator", sorted(ESTIMATORS))
@pytest.mark.parametrize("method", sorted(METHODS))
def test_each_combination_builds_its_strategies(method, estimator, td_estimator):
    agent = QLearningLQR(
        linear_env(*SYSTEM),
        method=method,
        estimator=estimator,
        td_estimator=td_estimator,
        tol=1e-7,
        rls_initial_covariance=3.0,
        rls_forgetting=0.5,
        max_warmup_iterations=17,
    )
    strategies = agent.strategies
    method_class, reuses = METHODS[method]
    assert type(strategies.method) is method_class
    assert strategies.method.reuse_data is reuses is agent.reuse_data
    assert strategies.method.tol == 1e-7
    assert agent.method == ("policy_iteration" if method == "lspi" else method)  # the public string attribute
    if method_class is PolicyIteration:
        assert type(strategies.method.stabilizer) is DiscountAnnealing  # the default
        assert strategies.method.stabilizer.max_iterations == 17
    assert type(strategies.estimator) is ESTIMATORS[estimator]
    if estimator == "rls":
        assert (strategies.estimator.initial_covariance, strategies.estimator.forgetting) == (3.0, 0.5)
    assert type(strategies.evaluation) is TD_ESTIMATORS[td_estimator]
    assert strategies.evaluation.estimator is strategies.estimator
    assert strategies.evaluation.basis is agent.basis


@pytest.mark.parametrize("stabilize", sorted(STABILIZERS))
def test_stabilize_builds_policy_iterations_warmup(stabilize):
    agent = QLearningLQR(linear_env(*SYSTEM), method="lspi", stabilize=stabilize, max_warmup_iterations=9)
    warmup = agent.strategies.method.stabilizer
    assert type(warmup) is STABILIZERS[stabilize] and warmup.max_iterations == 9
    assert QLearningLQR(linear_env(*SYSTEM), reuse_data=False).strategies.method.reuse_data is False


@pytest.mark.parametrize("estimator", sorted(ESTIMATORS))
@pytest.mark.parametrize("method", sorted(METHODS))
def test_learning_runs_through_the_built_strategies(method, estimator, monkeypatch):
    """Every least-squares solve goes through the chosen estimator (never the other one): VI
    through its fitted-Q regression, PI through LSTD-Q policy evaluation."""
    calls: list[tuple[str, str]] = []
    for cls in ESTIMATORS.values():
        for solve in ("instrumental", "least_squares"):
            original = getattr(cls, solve)

            def spy(self, *args, _original=original, _solve=solve, **kwargs):
                calls.append((self.name, _solve))
                return _original(self, *args, **kwargs)

            monkeypatch.setattr(cls, solve, spy)
    agent = QLearningLQR(
        linear_env(*SYSTEM),
        method=method,
        estimator=estimator,
        seed=0,
        exploration_std=1.0,
        initial_gain=None if method == "value_iteration" else np.zeros((1, 2)),
        discount=0.1,  # K = 0 is stabilizing (√γ ρ(A) < 1)
    )
    agent.learn(samples_per_iteration=6)
    expected = "least_squares" if method == "value_iteration" else "instrumental"
    assert calls and set(calls) == {(estimator, expected)}
    assert {h["phase"] for h in agent.history} == {method if method == "value_iteration" else "policy_iteration"}
    assert agent.stop_reason == "converged"


@pytest.mark.parametrize(
    ("option", "accepted"),
    [
        ("method", ["lspi", "policy_iteration", "value_iteration"]),
        ("estimator", ["batch", "rls"]),
        ("td_estimator", ["lstd", "lstd_gls", "matrix_bellman", "ols"]),
        ("sampling", ["reset", "trajectory"]),
        ("stabilize", ["value_iteration", "discount_annealing"]),
    ],
)
def test_an_unknown_name_is_a_value_error_listing_the_accepted_ones(option, accepted):
    with pytest.raises(ValueError, match=f"^{option} must be") as err:
        QLearningLQR(linear_env(*SYSTEM), **{option: "sarsa"})
    message = str(err.value)
    assert "'sarsa'" in message
    assert all(repr(name) in message for name in accepted), message
