"""Learning agents (the Q-learning LQR, Stable-Baselines3 glue)."""
