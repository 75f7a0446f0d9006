#!/usr/bin/env python3
"""What FMI 3.0 costs the harness against FMI 2.0, measured side by side in one run (interleaved,
median of repeats): the same object through both versions' binaries, which share their C core.

  * recording: SimplePendulum, rk4 at its default h, 10 s with 1001 output points (the recorder's
    loop: one step and one get per point; FMI 3.0's get and step go through small adapters);
  * co-simulation: the coupled scene, Gauss-Seidel with held inputs, 1000 macro steps, through the
    master's C loop, all FMI 2.0 against spring and pendulums in FMI 3.0; the loop and the set-up
    (loading and instantiating the three FMUs) timed apart.

Both versions do the same work (the evaluation counts are printed and equal), so the ratio is
the harness's calling overhead alone.
"""
from __future__ import annotations

import dataclasses
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from harness.cosim.master import Master, MasterOptions  # noqa: E402
from harness.cosim.system import load_system  # noqa: E402
from harness.fmi.fmu_instance import FmuInstance  # noqa: E402
from harness.fmi.fmus import build_dir, build_fmus  # noqa: E402
from harness.fmi.simulation import Recorder, communication_grid  # noqa: E402

REPEATS = 15


def recorder_run(version_folder: str):
    instance = FmuInstance(build_dir() / "fmus" / version_folder / "SimplePendulum.fmu")
    recorder = Recorder(instance, communication_grid(0.0, 10.0, 0.01), ["x", "y", "n_rhs"])

    def run() -> int:
        instance.reset()
        instance.initialize(0.0, solver="rk4")
        return int(recorder.run()["n_rhs"][-1])
    return instance, run


def master_run(system, setups: list[float]):
    def run() -> int:
        start = time.perf_counter()
        with Master(system, MasterOptions(stop=10.0, step=0.01, extrapolation="hold")) as master:
            setups.append(time.perf_counter() - start)
            result = master.run()
        return int(result["left.n_rhs"][-1]), time.perf_counter() - start - setups[-1]
    return run


def timed(run) -> tuple[float, int]:
    start = time.perf_counter()
    count = run()
    if isinstance(count, tuple):  # the run timed itself (its set-up apart)
        return count[1], count[0]
    return time.perf_counter() - start, count


def main() -> int:
    build_fmus()
    two, record_two = recorder_run("")
    three, record_three = recorder_run("fmi3")
    with load_system(ROOT / "scenes" / "coupled_pendulums.json") as system:
        mixed = dataclasses.replace(system, components=[
            dataclasses.replace(c, fmu=build_dir() / "fmus" / "fmi3" / Path(c.fmu).name) for c in system.components])
        setups: dict[str, list[float]] = {"2.0": [], "3.0": []}
        runs = {"record FMI 2.0": record_two, "record FMI 3.0": record_three,
                "co-simulate FMI 2.0": master_run(system, setups["2.0"]),
                "co-simulate FMI 3.0": master_run(mixed, setups["3.0"])}
        times: dict[str, list[float]] = {name: [] for name in runs}
        counts: dict[str, int] = {}
        for _ in range(REPEATS):  # interleaved: a noisy neighbour slows both sides alike
            for name, run in runs.items():
                seconds, counts[name] = timed(run)
                times[name].append(seconds)
    two.free()
    three.free()
    medians = {name: statistics.median(values) for name, values in times.items()}
    print(f"{'run':22s} {'median':>10s} {'evaluations':>12s}")
    for name, seconds in medians.items():
        print(f"{name:22s} {seconds * 1e3:8.2f} ms {counts[name]:12d}")
    for what, points in (("record", 1001), ("co-simulate", 1000)):
        a, b = medians[f"{what} FMI 2.0"], medians[f"{what} FMI 3.0"]
        print(f"{what}: FMI 3.0 / FMI 2.0 = {b / a:.2f} ({(b - a) / points * 1e6:+.2f} us per point)")
    print(f"co-simulation set-up (three instances): FMI 2.0 {statistics.median(setups['2.0']) * 1e3:.1f} ms, "
          f"FMI 3.0 {statistics.median(setups['3.0']) * 1e3:.1f} ms")
    same = counts["record FMI 2.0"] == counts["record FMI 3.0"] and \
        counts["co-simulate FMI 2.0"] == counts["co-simulate FMI 3.0"]
    print("the same evaluations in both versions" if same else "the evaluation counts differ")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
