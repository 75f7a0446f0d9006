"""The FMUs' integration methods by name and order (the `Solver` enumeration)."""
from __future__ import annotations

FIXED_STEP = ("euler", "midpoint", "heun", "rk3", "rk4", "nystrom5", "ab2", "ab3", "ab4", "ab5", "ab6")
ORDER = {"euler": 1, "midpoint": 2, "heun": 2, "rk3": 3, "rk4": 4, "nystrom5": 5, "rkf45": 4,
         "ab2": 2, "ab3": 3, "ab4": 4, "ab5": 5, "ab6": 6}
