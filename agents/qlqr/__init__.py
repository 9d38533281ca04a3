"""The model-free Q-learning LQR (:class:`QLearningLQR`): learns the optimal linear state
feedback from data only.

It fits a quadratic Q-function ``Q(x, u) = [x; u]ᵀH[x; u]`` (Bradtke, Ydstie & Barto 1994;
Lewis & Vrabie 2009) and implements the method of the Q-learning LQR paper (Heravi &
Novinzadeh 2017, 1000 kg·m² satellite). The agent reads only what a flight computer has: its
measured state (``info["measured"]``, or the observation), the input it commanded
(``info["commanded"]``) and ``info["cost"]`` (:mod:`agents.qlqr.data`), never the ground
truth ``info["truth"]``; the env's model is used for reporting only (closed-loop spectral
radius, the reference optimum), never for learning.

Modules, each with one job:

* ``agent`` — :class:`QLearningLQR`: options, dispatch from option names to strategies, the
  policy interface, the certainty-equivalence comparison.
* ``value_iteration``, ``policy_iteration`` — the ``method`` strategies (LSPI is policy
  iteration on one reused batch); ``stabilizers`` — policy iteration's ``stabilize``
  strategies (discount annealing, value-iteration warm-up) and the data Lyapunov test.
* ``evaluation`` — the policy-evaluation (``td_estimator``) strategies: LSTD-Q, feasible-GLS
  LSTD-Q, OLS Bellman residual, matrix Bellman equation.
* ``estimators`` — the least-squares solvers (QR, LSTD-Q, RLS, excitation guard, greedy gain,
  variance weights) and the ``estimator`` strategies (batch, recursive).
* ``basis`` — the regression of a batch: scaled quadratic features, row weights, the guarded
  design, θ ↔ H; ``features`` — the orthonormal svec basis.
* ``sampling`` — the agent's data supply (seeded batches, sample count, input-signal guard);
  ``data`` — transition collection from a Gymnasium env.
* ``context`` — what the strategies of one ``learn()`` call share; ``trace`` — gain, kernel,
  history, stop reason; ``nominal`` — the env's nominal model (reporting only).
* ``certainty_equivalence`` — least-squares model + Riccati on the same data (the reference);
  ``truth`` — model-based ground truth for tests, reproductions and benchmarks.
"""

from agents.qlqr.agent import QLearningLQR

__all__ = ["QLearningLQR"]
