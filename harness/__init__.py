"""Harness for the pendulum FMUs: build, simulate, chart.

    from harness import simulate, locate_fmu
    result = simulate(locate_fmu("SimplePendulum"), stop_time=10.0, step=0.01, solver="rk4", h=0.008)
    result.write_csv("simple.csv")
"""
from harness.errors import HarnessError

__all__ = ["FMU_NAMES", "HarnessError", "SimulationResult", "locate_fmu", "simulate"]


def __getattr__(name: str):
    """The library's entry points, imported when first used: the command line starts (and answers
    Ctrl-C) before fmpy and numpy are loaded."""
    if name in ("FMU_NAMES", "locate_fmu"):
        from harness.fmi import fmus
        return getattr(fmus, name)
    if name in ("SimulationResult", "simulate"):
        from harness.fmi import simulation
        return getattr(simulation, name)
    raise AttributeError(f"module 'harness' has no attribute {name!r}")
