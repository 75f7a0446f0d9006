#!/usr/bin/env python3
"""The master that sees impacts against the fixed-step masters and the energy step control, on Newton's
cradle of five pendulum FMUs joined by four Contact elements (scenes/contact_cradle.json: steel balls,
ball 1 let go from 0.5 rad, the strike at 0.279 s), side by side in one run, one master after the other
in this process.

The masters and what is measured are the contact study's (harness/studies/contact_study.py, also
`harness chart contacts`): each runs the scene to 0.3 s, just past the strike, against the scene's
monolithic reference (its contacts located as events); the error is that of the balls' outgoing
velocities relative to the fastest, the energy created is relative to the cradle's largest kinetic energy
and given per contact onset. Macro steps are machine-independent; seconds are this machine's. Then the
macro steps each master needs for an error of 1e-4 (log-log interpolation between the bracketing runs) and
the ratio of the best fixed-step master's to the impact-aware master's (goal: at least 20), and the energy
the impact-aware master creates per contact onset (goal: below 1e-6 of the cradle's energy). Last, the
impact-aware master at 100 steps per contact in the master's C loop and in its Python loop, alternately
(the same macro steps, bit for bit): the time per macro step of each and their ratio.

Then, by output interval (1e-5 to 1e-2 s), the cradle that stepped through its strike at an ordinary interval
(harness.scene.contact_scenes.released_cradle: each ball's solver at its default, the strike at 0.355 s) with no
option, that is with the default contact steps, in the C loop and the Python loop side by side: macro steps,
rollbacks and the balls' velocity error from 2 ms after the strike on (relative to the impact speed) against the
monolithic reference; and the same scene in plain macro steps of each interval, which the energy check stops.

Usage: python benchmarks/contact_benchmark.py [--quick] [--repeats 3]
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import time  # noqa: E402

from harness.cosim.master import Master, MasterOptions  # noqa: E402
from harness.cosim.system import load_system  # noqa: E402
from harness.fmi.fmus import build_fmus  # noqa: E402
from harness.scene.contact_scenes import released_cradle  # noqa: E402
from harness.studies.contact_study import TARGET, contact_sweep, steps_needed  # noqa: E402
from harness.studies.monolithic import MonolithicScene  # noqa: E402

STOP = 0.3


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="no fixed step below 2e-6 s, at most 200 steps per contact")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats per run; the median is kept")
    args = parser.parse_args(argv)
    build_fmus()
    with load_system(ROOT / "scenes" / "contact_cradle.json") as system:
        points = contact_sweep(system, stop=STOP, repeats=args.repeats, quick=args.quick, workers=1)
        loops = compare_loops(system, args.repeats)
    print(f"{'master':36s} {'setting':14s} {'macro steps':>11s} {'error':>9s} {'energy':>10s} {'per onset':>10s} "
          f"{'seconds':>8s}")
    for p in points:
        print(f"{p.master:36s} {p.setting:14s} {p.macro_steps:11d} {p.error:9.2e} {p.energy:10.2e} "
              f"{p.per_onset:10.2e} {p.seconds:8.3f}")
    needed = steps_needed(points)
    print(f"\nmacro steps at an error of {TARGET:g} (between the bracketing runs):")
    for name, steps in needed.items():
        print(f"  {name:36s} " + (f"{steps:10.0f}" if math.isfinite(steps) else "not bracketed"))
    fixed = [s for name, s in needed.items() if name.startswith("fixed") and math.isfinite(s)]
    aware = needed["contact steps"]
    if fixed and math.isfinite(aware):
        print(f"the best fixed-step master takes {min(fixed) / aware:.0f} times the macro steps of the impact-aware "
              "master at that error (goal: at least 20)")
    reaching = [p for p in points if p.master.startswith("contact steps") and p.error <= TARGET]
    for p in reaching:
        print(f"{p.master}, {p.setting}: error {p.error:.2g}, energy created per contact onset {abs(p.per_onset):.2g} "
              "of the largest kinetic energy (goal: below 1e-6)")
    (c_steps, c_seconds), (py_steps, py_seconds) = loops["C"], loops["Python"]
    print(f"--contact-steps 100, {c_steps} macro steps: C loop {1e6 * c_seconds / c_steps:.1f} us per macro step, "
          f"Python loop {1e6 * py_seconds / py_steps:.1f} us: {py_seconds / c_seconds:.1f} times")
    by_interval((1e-4, 1e-3, 1e-2) if args.quick else (1e-5, 1e-4, 1e-3, 1e-2))
    return 0


def by_interval(intervals: tuple[float, ...]) -> None:
    """The released cradle at each output interval: default contact steps in both loops, then plain steps."""
    print(f"\nthe released cradle to 0.5 s by output interval, default options ({'macro steps':>11s}, rollbacks, "
          "velocity error after the strike of the impact speed; seconds C | Python):")
    folder = Path(tempfile.mkdtemp())
    try:
        for interval in intervals:
            path = folder / f"cradle_{interval:g}.json"
            path.write_text(json.dumps(released_cradle(interval)))
            with load_system(path) as system:
                runs = {}
                for name, native, options in (("C", True, {}), ("Python", False, {}),
                                              ("plain", True, {"contact_steps": 0})):
                    with Master(system, MasterOptions(stop=system.stop, step=interval, **options)) as master:
                        master.use_native = native
                        start = time.perf_counter()
                        runs[name] = (master.run(), time.perf_counter() - start)
                scene = MonolithicScene(system)
                columns = scene.solve(runs["C"][0].time)
            (c, c_seconds), (py, py_seconds), (plain, _) = runs["C"], runs["Python"], runs["plain"]
            after = c.time >= scene.events[0][0] + 2e-3
            speed = max(abs(float(v)) for k in range(1, 6) for v in columns[f"ball{k}.v_x"])
            error = max(float(abs(c[f"ball{k}.v_x"][after] - columns[f"ball{k}.v_x"][after]).max())
                        for k in range(1, 6)) / speed
            same = "the same bits" if (c.values == py.values).all() else "NOT the same bits"
            print(f"  {interval:7g} s {c.macro_steps:11d} {c.retries:3d} {error:9.2e}   {c_seconds:6.3f} | "
                  f"{py_seconds:6.3f} s ({same}); plain steps: "
                  + (f"stopped at t = {plain.stopped_at:.6g} s" if plain.stopped_at is not None else
                     f"ran through, energy residual {plain.energy_residual:.2e} J"))
    finally:
        shutil.rmtree(folder)


def compare_loops(system, repeats: int) -> dict[str, tuple[int, float]]:
    """(macro steps, best seconds) of the contact steps in the C loop and in the Python loop, run alternately."""
    best: dict[str, tuple[int, float]] = {}
    for _ in range(max(repeats, 1)):
        for name, native in (("C", True), ("Python", False)):
            with Master(system, MasterOptions(stop=STOP, step=0.01, contact_steps=100)) as master:
                master.use_native = native
                start = time.perf_counter()
                result = master.run()
                seconds = time.perf_counter() - start
            if name not in best or seconds < best[name][1]:
                best[name] = (result.macro_steps, seconds)
    return best


if __name__ == "__main__":
    sys.exit(main())
