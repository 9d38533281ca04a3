"""The cited flight values of Magnetorquer (:mod:`attitude_envs.presets.flight`): none yet."""
