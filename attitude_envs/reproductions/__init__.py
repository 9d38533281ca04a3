"""Paper reproductions, one module each, run by ``train.py reproduce <id> --out DIR``.

Each entry maps a reproduction id to ``"module:function"``; the function takes
``(out_dir: Path, quick: bool)`` and returns the list of
:class:`attitude_envs.evaluation.reproduction.Row` it wrote with
:func:`attitude_envs.evaluation.reproduction.write_reproduction`.
"""

REPRODUCTIONS: dict[str, str] = {
    "fault-tolerant-smc": "attitude_envs.reproductions.fault_tolerant_smc:reproduce",
}
