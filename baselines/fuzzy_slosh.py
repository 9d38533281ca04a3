"""Mamdani fuzzy gain-scheduled P/PD of Navabi & Davoodi's fuel-slosh paper (eqs. 32–36), on
scikit-fuzzy.

Two Mamdani systems built with :mod:`skfuzzy.control`:

* attitude block, inputs e = −θ and ė = −Ω (normalized by 2° and 1.5e-4 rad/s and
  saturated to [−1, 1]), outputs K'_2 (P gain, paper Table 1) and K'_3 (D gain, Table 2);
* v_z block, inputs e = −v_z and ė = −v̇_z (100 m/s, 0.6 m/s²), output K'_1 from the
  two-rule base "e ZO and ė ZO → S, otherwise → B" (assumed: the paper's names are lost).

Inputs have 7 sets NB…PB (trapezoidal shoulders, triangles centred at ±1/3, ±2/3, 0,
half-width 1/3); outputs S and B are Gaussians at 0 and 1 (σ = 0.4247); min/max
inference, centroid defuzzification (assumed where the paper is silent). Gains:
k_j = (k_j,max − k_j,min) K'_j + k_j,min with Table 6 as printed (row 3 has min > max). v̇_z = u1(previous step) + v_x Ω.

``schedule_period_s``: the fuzzy systems are re-evaluated at most this often (default
1 s, ≈ 1/100 of the loop time constants) and the gains held in between; the PD law itself
runs every control step.
"""

from __future__ import annotations

import math

import numpy as np
import skfuzzy as fuzz
from skfuzzy import control as ctrl

from attitude_envs import validation
from baselines.slosh import NewInputPolicy

LABELS = ("NB", "NM", "NS", "ZO", "PS", "PM", "PB")
# Paper Table 1 (P-type K') and Table 2 (D-type K'); rows e, columns ė, both NB…PB, as printed.
TABLE_P = ("BBBBBBB", "SBBBBBS", "SSBBBSS", "SSSBSSS", "SSBBBSS", "SBBBBBS", "BBBBBBB")
TABLE_D = ("SSSSSSS", "BBSSSBB", "BBBSBBB", "BBBBBBB", "BBBSBBB", "BBSSSBB", "SSSSSSS")
# Paper Table 6 gain ranges (k_min, k_max), as printed.
GAIN_RANGES = {"k1": (3.84e-3, 7.2e-3), "k2": (2.65e-5, 5.0e-5), "k3": (1.2e-2, 6e-3)}
SCALES = {"vz": 100.0, "dvz": 0.6, "theta": math.radians(2.0), "dtheta": 1.5e-4}
SIGMA = 0.4247


class _FixedControlSystem(ctrl.ControlSystem):
    """A ControlSystem whose rule firing order is computed once.

    scikit-fuzzy 0.5.0 rebuilds the rule order (networkx graph composition) on every
    access of ``ControlSystem.rules``, i.e. several times per ``compute()`` (≈ 75 ms per
    evaluation of the 49-rule system). Our rule bases never change after construction, so
    the order is cached; the inference itself is unchanged scikit-fuzzy.
    """

    _order: list | None = None

    @property
    def rules(self):
        if self._order is None:
            return ctrl.ControlSystem.rules.fget(self)
        return iter(self._order)

    def freeze(self) -> _FixedControlSystem:
        self._order = list(ctrl.ControlSystem.rules.fget(self))
        return self


def _input(name: str) -> ctrl.Antecedent:
    var = ctrl.Antecedent(np.linspace(-1.0, 1.0, 241), name)
    u = var.universe
    var["NB"] = fuzz.trapmf(u, [-2.0, -2.0, -1.0, -2.0 / 3.0])
    var["PB"] = fuzz.trapmf(u, [2.0 / 3.0, 1.0, 2.0, 2.0])
    for label, centre in zip(LABELS[1:-1], (-2 / 3, -1 / 3, 0.0, 1 / 3, 2 / 3), strict=True):
        var[label] = fuzz.trimf(u, [centre - 1 / 3, centre, centre + 1 / 3])
    return var


def _output(name: str) -> ctrl.Consequent:
    var = ctrl.Consequent(np.linspace(0.0, 1.0, 201), name, defuzzify_method="centroid")
    var["S"] = fuzz.gaussmf(var.universe, 0.0, SIGMA)
    var["B"] = fuzz.gaussmf(var.universe, 1.0, SIGMA)
    return var


def attitude_system() -> ctrl.ControlSystem:
    """Mamdani system (e, ė) → (K'_P from Table 1, K'_D from Table 2)."""
    e, de = _input("e"), _input("de")
    kp, kd = _output("kp"), _output("kd")
    rules = []
    for i, le in enumerate(LABELS):
        for j, lde in enumerate(LABELS):
            rules.append(ctrl.Rule(e[le] & de[lde], (kp[TABLE_P[i][j]], kd[TABLE_D[i][j]])))
    return _FixedControlSystem(rules).freeze()


def velocity_system() -> ctrl.ControlSystem:
    """Mamdani system (e, ė) → K'_1 with the two-rule base (assumed, see the module docstring)."""
    e, de = _input("e"), _input("de")
    k = _output("k")
    zo = e["ZO"] & de["ZO"]
    return _FixedControlSystem([ctrl.Rule(zo, k["S"]), ctrl.Rule(~zo, k["B"])]).freeze()


def _evaluate(sim: ctrl.ControlSystemSimulation, e: float, de: float) -> dict[str, float]:
    sim.input["e"] = float(np.clip(e, -1.0, 1.0))
    sim.input["de"] = float(np.clip(de, -1.0, 1.0))
    sim.compute()
    return dict(sim.output)


class FuzzySloshPDPolicy(NewInputPolicy):
    """Fuzzy gain-scheduled P/PD (Mamdani, scikit-fuzzy); see the module docstring."""

    name = "fuzzy"
    stateful = True  # gains held between schedule updates: simulate sampled, not in an ODE solver

    def __init__(self, env, schedule_period_s: float = 1.0, inversion: str = "nonlinear") -> None:
        super().__init__(env, inversion)
        period = validation.positive("schedule_period_s", schedule_period_s)
        self._every = max(1, round(period / self.model.control_dt_s))
        self._att = ctrl.ControlSystemSimulation(attitude_system(), cache=False)
        self._vel = ctrl.ControlSystemSimulation(velocity_system(), cache=False)
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._count = 0
        self.gains = np.array([np.mean(GAIN_RANGES[k]) for k in ("k1", "k2", "k3")])

    def schedule(self, x: np.ndarray, v_x: float) -> np.ndarray:
        """Gains ``[k1, k2, k3]`` from the fuzzy systems at ``x`` (eqs. 34–36)."""
        dvz = self.last_new_inputs[0] + v_x * x[2]
        att = _evaluate(self._att, -x[1] / SCALES["theta"], -x[2] / SCALES["dtheta"])
        vel = _evaluate(self._vel, -x[0] / SCALES["vz"], -dvz / SCALES["dvz"])
        primes = (vel["k"], att["kp"], att["kd"])
        return np.array(
            [lo + (hi - lo) * kp for (lo, hi), kp in zip(GAIN_RANGES.values(), primes, strict=True)], dtype=float
        )

    def new_inputs(self, x: np.ndarray, v_x: float) -> np.ndarray:
        if self._count % self._every == 0:
            self.gains = self.schedule(x, v_x)
        self._count += 1
        k1, k2, k3 = self.gains
        return np.array([-k1 * x[0], -k2 * x[1] - k3 * x[2]])
