"""What the scene planner and the coupled planner share: the plan of one object, the default it is
measured against, and the step-doubling prediction of a candidate's error (see `harness.studies.planner`).
Kept apart from both planners so that the planner can dispatch to the coupled one without the two
importing each other."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from harness.fmi.methods import plan_settings

DEFAULT = ("rk4", 0.008)  # the coupled pendulums'; a single object's default is rk4 at its own h
SAFETY = 0.5


@dataclass
class ObjectPlan:
    object: str
    kind: str  # the FMU's model identifier
    model: str  # "nonlinear", or "linear" (SimplePendulum's closed form)
    method: str  # "closed form" for the linear model
    h: float  # internal step [s] (the frame interval for the closed form)
    predicted_error: float  # metres
    verified_error: float  # metres, against the tight reference
    cost: int  # evaluations over the scene (right-hand side, or closed form)
    default_error: float  # rk4 at the object's default h, verified the same way
    default_cost: int
    how: str  # how the error was predicted
    tolerance: float
    communication_step: float = math.nan  # coupled objects only
    plan: str = "pointwise"  # or "plausible" (harness.studies.chaos), for a motion that parts too fast
    lyapunov: float = math.nan  # 1/s: the largest finite-time Lyapunov exponent over the scene
    horizon: float = math.nan  # s: the predictability horizon for the tolerance
    energy_error: float = math.nan  # J: a plausible plan's largest energy error over the scene
    energy_limit: float = math.nan  # J: what one pixel of the centre of mass's height shows

    @property
    def settings(self) -> dict:
        """The start values that run the plan's model, method and step."""
        return {"model": "linear", "h": self.h} if self.model == "linear" else plan_settings(self.method, self.h)


def largest_distance(a: np.ndarray, b: np.ndarray) -> float:
    d = np.linalg.norm(a - b, axis=-1)
    return float(np.max(d)) if np.all(np.isfinite(d)) else math.inf


def step_doubling(run, order: int, tolerance: float) -> float | None:
    """Predicted error of run(1) from run(1), run(1/2) and, unless the difference is already below a
    hundredth of the tolerance, run(1/4) to check the order (see the module text). `run(scale)`
    gives the positions with every step scaled; None: a run failed or the order did not show."""
    coarse = run(1.0)
    if not np.all(np.isfinite(coarse)):
        return None
    half = run(0.5)
    first = largest_distance(coarse, half)
    if not math.isfinite(first):
        return None
    if first > tolerance / 100:
        second = largest_distance(half, run(0.25))
        if not (second > 0 and 2 ** order / 2.5 <= first / second <= 2 ** order * 2.5):
            return None
    return first * 2 ** order / (2 ** order - 1)
