"""8 instances of each FMU stepped in parallel threads give results bit-identical to sequential runs
(ctypes releases the GIL during fmi2DoStep, so the threads really run the C code concurrently)."""
from __future__ import annotations

import threading

import pytest

from harness.fmi.fmu_instance import OK, FmuInstance
from harness.fmi.fmus import FMU_NAMES
from harness.objects.registry import compliant_names

from conftest import ELEMENT_MOTION, ELEMENTS

OUTPUTS = {"SimplePendulum": ("phi", "omega", "x", "E"), "DoublePendulum": ("phi1", "phi2", "x2", "E"),
           "SpringPendulum": ("phi", "eps", "x", "E"), "Spring": ("Fa_x", "Fa_y", "E_pot"),
           "Contact": ("Fa_x", "Fa_y", "gap", "E_pot")}
SOLVERS = ("rk4", "ab4", "rkf45", "nystrom5", "heun", "ab6", "euler", "rk3")


def run(instance: FmuInstance, name: str, k: int) -> list[float]:
    if name in ELEMENTS:  # ends that move, and differently in each thread
        instance.initialize(**{**ELEMENT_MOTION[name], "b_vx": 0.1 * k})
    elif name in compliant_names():  # its contacts are too stiff for the fixed steps at this h (which say so)
        instance.initialize(solver="rkf45", h=0.002, d=0.01 * k)
    else:
        instance.initialize(solver=SOLVERS[k], h=0.002, d=0.01 * k)
    for i in range(200):
        assert instance.do_step(i * 0.01, 0.01) == OK
    return instance.get(*OUTPUTS.get(name, ("E_kin", "E_pot", "E")))


@pytest.mark.parametrize("name", FMU_NAMES)
def test_parallel_threads_match_sequential_runs(fmu_paths, unzipped, name):
    instances = [FmuInstance(fmu_paths[name], unzipdir=unzipped[name], name=f"{name}{k}") for k in range(8)]
    try:
        sequential = []
        for k in range(8):
            with FmuInstance(fmu_paths[name], unzipdir=unzipped[name]) as alone:
                sequential.append(run(alone, name, k))
        results: list = [None] * 8
        barrier = threading.Barrier(8)

        def worker(k: int) -> None:
            barrier.wait()
            results[k] = run(instances[k], name, k)

        threads = [threading.Thread(target=worker, args=(k,)) for k in range(8)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert results == sequential
    finally:
        for instance in instances:
            instance.free()
