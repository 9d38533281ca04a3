"""Building blocks of the model-free Q-learning LQR agent (:class:`agents.QLearningLQR`).

``features`` (quadratic svec basis), ``estimators`` (least squares, LSTD-Q, RLS, excitation
guard, greedy gain), ``data`` (transition collection from a Gymnasium env),
``certainty_equivalence`` (least-squares model + Riccati reference on the same data).
"""
