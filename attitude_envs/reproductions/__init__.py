"""Paper reproductions, one module each, run by ``train.py reproduce <id> --out DIR``.

Each entry maps a reproduction id to ``"module:function"``; the function takes
``(out_dir: Path, quick: bool)`` and returns the list of
:class:`attitude_envs.evaluation.reproduction.Row` it wrote with
:func:`attitude_envs.evaluation.reproduction.write_reproduction`.
"""

REPRODUCTIONS: dict[str, str] = {
    "feedback-linearization": "attitude_envs.reproductions.feedback_linearization:reproduce",
    "fuel-slosh": "attitude_envs.reproductions.fuel_slosh:reproduce",
    "q-learning-lqr": "attitude_envs.reproductions.q_learning_lqr:reproduce",
    "ga-pid": "attitude_envs.reproductions.ga_pid:reproduce",
    "fault-tolerant-smc": "attitude_envs.reproductions.fault_tolerant_smc:reproduce",
}
