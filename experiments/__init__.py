"""Orchestration, the top layer: the command line, benchmark campaigns and reports, fault campaigns,
paper reproductions, the policy registry and the Stable-Baselines3 training glue.

Imports go strictly downwards (checked by ``lint-imports``, contracts in ``pyproject.toml``)::

    train.py → experiments → agents → baselines → attitude_envs
"""
