"""Paper reproductions, one module each, run by ``train.py reproduce <id> --out DIR``.

Each entry maps a reproduction id to ``"module:function"``; the function takes
``(out_dir: Path, quick: bool)`` and returns the list of
:class:`experiments.reproduction.Row` it wrote with
:func:`experiments.reproduction.write_reproduction`.
"""

REPRODUCTIONS: dict[str, str] = {
    "feedback-linearization": "experiments.reproductions.feedback_linearization:reproduce",
    "fuel-slosh": "experiments.reproductions.fuel_slosh:reproduce",
    "q-learning-lqr": "experiments.reproductions.q_learning_lqr:reproduce",
    "ga-pid": "experiments.reproductions.ga_pid:reproduce",
    "fault-tolerant-smc": "experiments.reproductions.fault_tolerant_smc:reproduce",
}
