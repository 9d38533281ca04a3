"""The cited flight values of LinearSystem (:mod:`attitude_envs.presets.flight`): none yet."""
