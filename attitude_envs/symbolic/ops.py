"""The CasADi executor of the plant definitions (:mod:`attitude_envs.plants.ops`): a
definition called with CasADi symbols builds the expressions of its equations."""

from __future__ import annotations

import casadi

from attitude_envs.plants.ops import Ops

#: CasADi: symbolic ``sin``/``cos``/``sqrt``/``fabs``, ``if_else`` for ``where``; helpers stay Python
CASADI = Ops("casadi", sin=casadi.sin, cos=casadi.cos, sqrt=casadi.sqrt, fabs=casadi.fabs, where=casadi.if_else)
