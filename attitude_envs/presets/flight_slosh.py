"""The cited flight values of FuelSlosh (:mod:`attitude_envs.presets.flight`): none yet."""
