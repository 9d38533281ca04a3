"""The CasADi executor of the plant definitions (:mod:`attitude_envs.plants.ops`): a
definition called with CasADi symbols builds the expressions of its equations."""

from __future__ import annotations

import casadi

from attitude_envs.plants.ops import library_ops


def _no_round(x):
    raise ValueError("round has no smooth CasADi expression: an optimal-control problem relaxes it (see the caller)")


#: CasADi: symbolic ``sin``/``cos``/``sqrt``/``fabs``/``fmin``/``fmax``/``sign``, ``if_else`` for
#: ``where``, no ``round`` (a quantized command is relaxed); helpers stay Python
CASADI = library_ops("casadi", casadi, "casadi", round=_no_round)
