"""attitude-envs: Gymnasium environments for spacecraft attitude control from five papers.

Importing the package registers the env ids ``attitude_envs/ReactionWheel-v0`` and
``attitude_envs/LinearSystem-v0`` (the only import-time side effect).
"""

from attitude_envs.registration import ENV_IDS, register_envs

__version__ = "0.1.0"

register_envs()

__all__ = ["ENV_IDS", "__version__", "register_envs"]
