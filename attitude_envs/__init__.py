"""attitude-envs: Gymnasium environments for spacecraft attitude control from five papers.

Importing the package registers all five env ids (the only import-time side effect):
``attitude_envs/ReactionWheel-v0``, ``attitude_envs/AirBearing-v0``,
``attitude_envs/LinearSystem-v0``, ``attitude_envs/FuelSlosh-v0`` and
``attitude_envs/Magnetorquer-v0``, each with a natively batched vector env
(``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``). Their named
parameter sets are in :mod:`attitude_envs.presets`.
"""

from attitude_envs.registration import ENV_IDS, register_envs

__version__ = "0.1.0"

register_envs()

__all__ = ["ENV_IDS", "__version__", "register_envs"]
