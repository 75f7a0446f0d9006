#!/usr/bin/env python3
"""Objects that touch against MuJoCo, the physics engine a user would pick for contact.

1. Newton's cradle (modelDescription/NewtonsCradle.toml: five balls of radius R on strings of length L,
   pivots 2 R apart, restitution 1, ball 1 let go from 0.5 rad). The textbook answer is exact: 0.1 s after
   the strike balls 1 to 4 are at rest and ball 5 moves as a pendulum released at the bottom with the
   impact speed (integrated here by scipy to 1e-13); after ten periods the energy is what it was. Measured:
   the largest error of the five angular velocities 0.1 s after the strike (relative to the impact speed),
   and the relative energy change after ten periods. MuJoCo: the same balls (point masses on massless
   rods about hinges, frictionless sphere contacts), under its documented elastic contact (solref with a
   negative stiffness and zero damping, two stiffnesses) with its Euler, RK4 and implicitfast integrators.
   The FMU: for gbs and nystrom5, the cheapest setting tried whose velocities are within 1e-9 rad/s and
   whose energy is within 1e-10.
2. The string pendulum (modelDescription/StringPendulum.toml, thrown at 5.5 m/s on a 1 m string): the time
   the string goes slack (where the tension of the circular motion vanishes, from the energy) and the
   time it jerks taut (where the parabola from there meets the circle), both exact. The FMU's are read
   from FMI 3.0 Co-Simulation, which returns early at each event (lastSuccessfulTime); MuJoCo's from a
   spatial tendon limited to the string's length (tuned: reference time constant two time steps, hard
   impedance), the bob on two slide joints, the slack time where the tendon's limit force reaches zero and
   the taut time where its length reaches L again, each interpolated linearly between steps. The FMU:
   for rk4, nystrom5 and gbs, the cheapest setting tried with both times within 1e-9 s.

Each run's computing time per simulated second, timed side by side (interleaved repeats, medians): the
FMU's as one fmi2DoStep over the whole run after its initialization, MuJoCo's as one mj_step call over as
many steps. The ratio of MuJoCo's best setting (the smallest error) to the FMU's fastest setting is the
goal's figure (at least 10).

Usage: python benchmarks/mujoco_benchmark.py [--repeats 3]   (MuJoCo: pip install -e ".[bench]")
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from scipy.integrate import quad, solve_ivp  # noqa: E402
from scipy.special import ellipk  # noqa: E402

from harness.fmi.events import event_times  # noqa: E402
from harness.fmi.fmu_instance import FmuInstance  # noqa: E402
from harness.fmi.fmus import build_fmus, locate_fmu  # noqa: E402
from harness.fmi.methods import SOLVERS  # noqa: E402

G = 9.81
CRADLE_L, CRADLE_R, CRADLE_M, CRADLE_PHI0 = 0.3, 0.02, 0.1, 0.5  # NewtonsCradle.toml's defaults
PERIOD = 4 * ellipk(math.sin(CRADLE_PHI0 / 2) ** 2) * math.sqrt(CRADLE_L / G)
IMPACT_SPEED = math.sqrt(2 * G / CRADLE_L * (1 - math.cos(CRADLE_PHI0)))
AFTER = 0.1  # seconds after the strike at which the velocities are compared
PERIODS = 10
STRING_L, STRING_V0 = 1.0, 5.5  # StringPendulum.toml's defaults
STRING_RUN = 1.5  # seconds: slack at 0.48 s, taut at 1.20 s


@dataclass
class Row:
    """One setting: its errors and its computing time per simulated second."""
    name: str
    errors: tuple[float, ...]
    run: object  # () -> None, the timed run
    simulated: float  # seconds the timed run covers
    seconds: list[float]
    unstable: bool = False  # MuJoCo found its accelerations non-finite or huge and reset the simulation


def mujoco_unstable(mujoco, data) -> bool:
    """Whether MuJoCo warned of non-finite or huge accelerations (after which it resets the state to rest)."""
    return any(data.warning[int(kind)].number > 0 for kind in (mujoco.mjtWarning.mjWARN_BADQACC,
                                                                mujoco.mjtWarning.mjWARN_BADQVEL,
                                                                mujoco.mjtWarning.mjWARN_BADQPOS))


def timed(run) -> float:
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


# ---------------------------------------------------------------- the exact answers

def pendulum(phi: float, omega: float, duration: float, L: float) -> np.ndarray:
    solution = solve_ivp(lambda t, s: [s[1], -G / L * math.sin(s[0])], (0.0, duration), [phi, omega],
                         method="DOP853", rtol=1e-13, atol=1e-14)
    return solution.y[:, -1]


def cradle_expected() -> np.ndarray:
    """The angular velocities of the five balls AFTER seconds after the strike."""
    return np.array([0.0, 0.0, 0.0, 0.0, pendulum(0.0, IMPACT_SPEED, AFTER, CRADLE_L)[1]])


def string_events() -> tuple[float, float]:
    """When the tension m (v^2 / L + g cos phi) of the circular motion vanishes, and when the parabola from
    there meets the circle again (after 4 v_y / g)."""
    phi = math.acos((2 * G - STRING_V0 ** 2 / STRING_L) / (3 * G))
    omega = lambda a: math.sqrt(STRING_V0 ** 2 / STRING_L ** 2 - 2 * G / STRING_L * (1 - math.cos(a)))  # noqa: E731
    slack, _ = quad(lambda a: 1.0 / omega(a), 0.0, phi, epsabs=1e-14, epsrel=1e-14)
    return slack, slack + 4 * STRING_L * omega(phi) * math.sin(phi) / G


# ---------------------------------------------------------------- the FMU

def fmu_settings(method: str, h: float, tol: float = 0.0) -> dict:
    return {"solver": SOLVERS.index(method) + 1, "h": h, "tol": tol}


def describe(method: str, settings: dict) -> str:
    return f"FMU {method} " + (f"tol {settings['tol']:g}" if settings["tol"] else f"h = {settings['h']:g}")


def fmu_cradle_errors(fmu: FmuInstance, settings: dict, expected: np.ndarray) -> tuple[float, float]:
    fmu.reset()
    fmu.initialize(**settings)
    fmu.do_step(0.0, PERIOD / 4 + AFTER)
    velocity = np.array(fmu.get(*[f"omega{i}" for i in range(1, 6)]))
    fmu.reset()
    fmu.initialize(**settings)
    energy = fmu.get("E")[0]
    fmu.do_step(0.0, PERIODS * PERIOD)
    return float(np.max(np.abs(velocity - expected))) / IMPACT_SPEED, abs(fmu.get("E")[0] / energy - 1.0)


def fmu_event_times(path: Path, settings: dict) -> list[float]:
    """The times at which FMI 3.0 Co-Simulation returned early (each event it handled) within STRING_RUN."""
    with FmuInstance(path, name="string", early_return=True) as instance:
        instance.initialize(**settings)
        return event_times(instance, np.array([0.0, STRING_RUN])).times


def fmu_run(fmu: FmuInstance, settings: dict, duration: float):
    """The timed run: one fmi2DoStep over `duration` from an initialized instance (set up untimed)."""
    def run():
        fmu.reset()
        fmu.initialize(**settings)
        start = time.perf_counter()
        fmu.do_step(0.0, duration)
        return time.perf_counter() - start
    return run


# ---------------------------------------------------------------- MuJoCo

def mujoco_cradle_model(mujoco, integrator: str, dt: float, solref: str):
    half = 2.0
    bodies = "".join(
        f'<body pos="{2 * CRADLE_R * (i - half)} 0 0"><joint type="hinge" axis="0 1 0"/>'
        f'<inertial pos="0 0 {-CRADLE_L}" mass="{CRADLE_M}" diaginertia="1e-12 1e-12 1e-12"/>'
        f'<geom type="sphere" size="{CRADLE_R}" pos="0 0 {-CRADLE_L}" mass="0" condim="1" solref="{solref}"/>'
        f'</body>' for i in range(5))
    return mujoco.MjModel.from_xml_string(
        f'<mujoco><compiler inertiafromgeom="false"/><option timestep="{dt}" gravity="0 0 -{G}" '
        f'integrator="{integrator}"/><worldbody>{bodies}</worldbody></mujoco>')


def mujoco_cradle(mujoco, integrator: str, dt: float, solref: str, expected: np.ndarray) -> Row:
    model = mujoco_cradle_model(mujoco, integrator, dt, solref)
    data = mujoco.MjData(model)

    def start():
        mujoco.mj_resetData(model, data)
        data.qpos[0] = CRADLE_PHI0  # about +y: ball 1 swings out to -x, away from the row (the FMU's phi1 = -0.5)
        mujoco.mj_forward(model, data)

    def energy() -> float:
        mujoco.mj_energyPos(model, data)
        mujoco.mj_energyVel(model, data)
        return float(data.energy.sum())
    start()
    mujoco.mj_step(model, data, nstep=round((PERIOD / 4 + AFTER) / dt))
    velocity = -np.array(data.qvel)  # the FMU's angles turn the other way
    unstable = mujoco_unstable(mujoco, data)
    start()
    before = energy()
    steps = round(PERIODS * PERIOD / dt)
    mujoco.mj_step(model, data, nstep=steps)
    unstable = unstable or mujoco_unstable(mujoco, data)
    errors = (float(np.max(np.abs(velocity - expected))) / IMPACT_SPEED, abs(energy() / before - 1.0))
    period_steps = round(PERIOD / dt)

    def run():
        start()
        begin = time.perf_counter()
        mujoco.mj_step(model, data, nstep=period_steps)
        return time.perf_counter() - begin
    return Row(f"MuJoCo {integrator} dt {dt:g} solref {solref}", errors, run, period_steps * dt, [], unstable)


def mujoco_string(mujoco, integrator: str, dt: float, exact: tuple[float, float]) -> Row:
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><option timestep="{dt}" gravity="0 0 -{G}" integrator="{integrator}"/><worldbody>'
        f'<site name="anchor"/><body><joint type="slide" axis="1 0 0"/><joint type="slide" axis="0 0 1"/>'
        f'<inertial pos="0 0 0" mass="1" diaginertia="1e-6 1e-6 1e-6"/><site name="bob"/></body></worldbody>'
        f'<tendon><spatial limited="true" range="0 {STRING_L}" solreflimit="{2 * dt} 1" '
        f'solimplimit="0.9999 0.9999 0.001"><site site="anchor"/><site site="bob"/></spatial></tendon></mujoco>')
    data = mujoco.MjData(model)

    def start():
        mujoco.mj_resetData(model, data)
        data.qpos[:] = [0.0, -STRING_L]
        data.qvel[:] = [STRING_V0, 0.0]
    start()
    steps = round(STRING_RUN / dt)
    # mj_step evaluates the constraint at the step's start: after it, force and length belong to time - dt
    times, force, length = np.empty(steps), np.empty(steps), np.empty(steps)
    for i in range(steps):
        mujoco.mj_step(model, data)
        times[i] = data.time - dt
        force[i] = data.efc_force[:data.nefc].sum() if data.nefc else 0.0
        length[i] = data.ten_length[0]
    unstable = mujoco_unstable(mujoco, data)
    if not np.any((force == 0.0) & (times > 0.1)):  # the string never went slack: no event to time
        return Row(f"MuJoCo {integrator} dt {dt:g}", (math.inf, math.inf), lambda: 0.0, steps * dt, [], True)
    slack_index = int(np.argmax((force == 0.0) & (times > 0.1)))  # the first step without tension
    a, b = force[slack_index - 2], force[slack_index - 1]  # the last two with it, extrapolated to zero
    slack = times[slack_index - 1] + (times[slack_index - 1] - times[slack_index - 2]) * b / (a - b)
    taut_index = slack_index + int(np.argmax(force[slack_index:] > 0.0))  # tension again, after the flight
    while length[taut_index - 1] >= STRING_L:  # back to where the length crossed L
        taut_index -= 1
    a, b = length[taut_index - 1] - STRING_L, length[taut_index] - STRING_L
    taut = times[taut_index - 1] + dt * a / (a - b)

    def run():
        start()
        begin = time.perf_counter()
        mujoco.mj_step(model, data, nstep=steps)
        return time.perf_counter() - begin
    return Row(f"MuJoCo {integrator} dt {dt:g}", (abs(slack - exact[0]), abs(taut - exact[1])), run, steps * dt, [],
               unstable)


# ---------------------------------------------------------------- side by side

def measure(rows: list[Row], repeats: int) -> None:
    for _ in range(repeats):  # interleaved: a noisy machine slows all alike
        for row in rows:
            row.seconds.append(row.run())


def report(title: str, columns: tuple[str, ...], rows: list[Row], goal: float) -> None:
    print(f"\n{title}")
    print(f"{'setting':44s} " + " ".join(f"{c:>12s}" for c in columns) + f" {'s per sim s':>12s}")
    cost = {row.name: statistics.median(row.seconds) / row.simulated for row in rows}
    for row in rows:
        note = "  (unstable: MuJoCo reset it)" if row.unstable else ""
        print(f"{row.name:44s} " + " ".join(f"{e:12.2e}" for e in row.errors) + f" {cost[row.name]:12.3e}{note}")
    fmus = [row for row in rows if row.name.startswith("FMU")]
    peers = [row for row in rows if not row.name.startswith("FMU") and not row.unstable]
    if not fmus:
        print(f"no FMU setting tried reaches {goal:g}")
        return
    fastest = min(fmus, key=lambda row: cost[row.name])
    if not peers:
        print("every MuJoCo setting tried was unstable")
        return
    best = min(peers, key=lambda row: max(row.errors))
    print(f"MuJoCo's best setting ({best.name}, error {max(best.errors):.1e}) takes "
          f"{cost[best.name] / cost[fastest.name]:.0f} times the computing of the FMU's fastest ({fastest.name}, "
          f"error {max(fastest.errors):.1e}); MuJoCo's cheapest setting "
          f"{min(cost[p.name] for p in peers) / cost[fastest.name]:.0f} times")


def cradle_rows(mujoco, fmu: FmuInstance) -> list[Row]:
    expected = cradle_expected()
    rows = []
    for method, candidates in (("gbs", [fmu_settings("gbs", 0.05, tol) for tol in (1e-9, 1e-10, 1e-11, 1e-12, 1e-13)]),
                               ("nystrom5", [fmu_settings("nystrom5", h) for h in (2e-3, 1e-3, 5e-4, 2.5e-4)])):
        for settings in candidates:
            errors = fmu_cradle_errors(fmu, settings, expected)
            if errors[0] * IMPACT_SPEED <= 1e-9 and errors[1] <= 1e-10:
                rows.append(Row(describe(method, settings), errors, fmu_run(fmu, settings, PERIOD), PERIOD, []))
                break
    for integrator, dt in (("Euler", 1e-4), ("Euler", 1e-5), ("RK4", 1e-4), ("implicitfast", 1e-4)):
        for solref in ("-1e6 0", "-1e8 0"):  # elastic: a direct stiffness and no damping
            rows.append(mujoco_cradle(mujoco, integrator, dt, solref, expected))
    return rows


def string_rows(mujoco, fmu: FmuInstance, fmi3: Path) -> list[Row]:
    exact = string_events()
    rows = []
    for method, candidates in (("rk4", [fmu_settings("rk4", h) for h in (1e-2, 5e-3, 2e-3, 1e-3, 5e-4)]),
                               ("nystrom5", [fmu_settings("nystrom5", h) for h in (1e-2, 5e-3, 2e-3, 1e-3)]),
                               ("gbs", [fmu_settings("gbs", 0.05, tol) for tol in (1e-8, 1e-10, 1e-12)])):
        for settings in candidates:
            times = fmu_event_times(fmi3, settings)
            if len(times) < 2:
                continue
            errors = (abs(times[0] - exact[0]), abs(times[1] - exact[1]))
            if max(errors) <= 1e-9:
                rows.append(Row(describe(method, settings), errors, fmu_run(fmu, settings, STRING_RUN), STRING_RUN, []))
                break
    for integrator, dt in (("Euler", 1e-3), ("Euler", 1e-4), ("Euler", 1e-5), ("RK4", 1e-4)):
        rows.append(mujoco_string(mujoco, integrator, dt, exact))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    try:
        import mujoco
    except ImportError:
        print("MuJoCo is not installed: pip install -e \".[bench]\" (./run bench installs it)", file=sys.stderr)
        return 2
    build_fmus()
    print(f"MuJoCo {mujoco.__version__}; cradle period {PERIOD:.4f} s, impact speed {IMPACT_SPEED:.4f} rad/s")
    with FmuInstance(locate_fmu("NewtonsCradle")) as cradle:
        rows = cradle_rows(mujoco, cradle)
        measure(rows, args.repeats)
        report("1. Newton's cradle: velocities 0.1 s after the strike (relative to the impact speed), energy after "
               f"{PERIODS} periods", ("velocities", "energy"), rows, 1e-9)
    with FmuInstance(locate_fmu("StringPendulum")) as string:
        rows = string_rows(mujoco, string, locate_fmu("fmi3/StringPendulum"))
        measure(rows, args.repeats)
        report("2. The string pendulum: errors of the slack and taut times (s)", ("slack", "taut"), rows, 1e-9)
    return 0


if __name__ == "__main__":
    sys.exit(main())
