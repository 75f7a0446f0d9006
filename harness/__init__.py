"""Harness for the pendulum FMUs: build, simulate, chart.

    from harness import simulate, locate_fmu
    result = simulate(locate_fmu("SimplePendulum"), stop_time=10.0, step=0.01, solver="rk4", h=0.008)
    result.write_csv("simple.csv")
"""
from harness.errors import HarnessError
from harness.fmi.fmus import FMU_NAMES, locate_fmu
from harness.fmi.simulation import SimulationResult, simulate

__all__ = ["FMU_NAMES", "HarnessError", "SimulationResult", "locate_fmu", "simulate"]
