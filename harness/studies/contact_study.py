"""Masters on a scene of objects that touch across FMUs (Contact elements): the impact-aware master
(`--contact-steps`), the fixed-step masters (Jacobi and Gauss-Seidel, inputs held or extrapolated linearly)
and the energy step control, each against the scene's monolithic reference, whose contacts are located as
events (`harness.studies.monolithic`).

Measured per run: macro steps (a machine-independent count); `error`, the largest error of any object
point's velocity at the run's end, relative to the fastest point's speed in the reference (after an
impact: the outgoing velocities); `energy`, the energy the run created (its total energy at the end less
that at the start) relative to the reference's largest kinetic energy, and that per contact onset of the
reference (`per_onset`); and seconds of the master's run (median of repeats; loading not included).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.cosim.master import MasterOptions
from harness.cosim.structure import System
from harness.errors import HarnessError
from harness.studies.coupling import timed_runs
from harness.studies.monolithic import MonolithicScene
from harness.studies.records import columns_of, read_records, write_records
from harness.studies.sweep import run_sweep

FIXED_STEPS = (1e-5, 4e-6, 2e-6, 1e-6)  # the fixed-step masters' macro steps [s]; held inputs stop at 2e-6
CONTACT_STEPS = (25, 50, 100, 200, 400)  # the impact-aware master's steps per contact
CORRECTED_STEPS = (50, 100, 200)  # ... with the energy correction
ENERGY_TOLERANCES = (1e-3, 1e-4)  # the energy step control's tolerances [J], largest step 1e-3 s
TARGET = 1e-4  # the error at which the masters' macro steps are compared


@dataclass
class ContactPoint:
    master: str
    setting: str
    macro_steps: int
    error: float  # relative; inf when the run stopped early
    energy: float  # created, relative to the reference's largest kinetic energy
    per_onset: float
    seconds: float


@dataclass(frozen=True)
class Reference:
    """What the runs are measured against: the velocity columns' values at the end, the speed scale, the
    energy scale and the number of contact onsets."""
    velocities: dict[str, float]
    speed: float
    energy: float
    onsets: int


def masters(interval: float, quick: bool = False) -> list[tuple[str, str, dict]]:
    """(master, setting, MasterOptions fields) of every run; `quick` leaves out the finest fixed steps and
    the largest numbers of steps per contact."""
    fixed = FIXED_STEPS[:3] if quick else FIXED_STEPS
    runs = []
    for algorithm in ("gauss-seidel", "jacobi"):
        for extrapolation in ("linear", "hold"):
            for h in fixed if extrapolation == "linear" else fixed[:3]:
                runs.append((f"fixed step, {algorithm}, {extrapolation}", f"H = {h:g} s",
                             dict(step=h, algorithm=algorithm, extrapolation=extrapolation, contact_steps=0)))
    for n in CONTACT_STEPS[:4] if quick else CONTACT_STEPS:
        runs.append(("contact steps", f"N = {n}", dict(step=interval, contact_steps=n)))
    for n in CORRECTED_STEPS:
        runs.append(("contact steps, energy correction", f"N = {n}",
                     dict(step=interval, contact_steps=n, energy_correction=True)))
    for tolerance in ENERGY_TOLERANCES:
        runs.append(("energy step control", f"{tolerance:g} J", dict(step=min(interval, 1e-3), energy_tol=tolerance)))
    return runs


def contact_reference(system: System, stop: float) -> Reference:
    """The scene's monolithic reference at its end, refused by name where the scene has no Contact."""
    scene = MonolithicScene(system)
    if not scene.contacts:
        raise HarnessError(f"{system.name}: the contact study needs a scene with Contact elements")
    times = np.linspace(0.0, stop, 201)
    columns = scene.solve(times)
    pairs = scene.point_columns("v_x", "v_y")
    velocities = {name: float(columns[name][-1]) for pair in pairs for name in pair}
    speed = max(math.hypot(columns[x][-1], columns[y][-1]) for x, y in pairs)
    kinetic = sum(np.asarray(columns[f"{c}.E_kin"]) for kind in scene.kinds.values() for c in kind.names)
    onsets = sum(what == "onset" for _, _, what in scene.events)
    return Reference(velocities, speed, float(np.max(kinetic)), onsets)


def measure(job: tuple) -> ContactPoint:
    """One master on the scene (runs in a worker)."""
    system, (name, setting, fields), stop, repeats, reference = job
    result, seconds = timed_runs(system, MasterOptions(stop=stop, **fields), repeats)
    if result.stopped_at is not None:
        error = created = math.inf
    else:
        error = max(abs(result[column][-1] - value) for column, value in reference.velocities.items()) / reference.speed
        created = float(result.energy[-1] - result.energy[0]) / reference.energy
    return ContactPoint(name, setting, result.macro_steps, float(error), created,
                        created / max(reference.onsets, 1), seconds)


def contact_sweep(system: System, stop: float | None = None, repeats: int = 3, quick: bool = False,
                  interval: float = 0.01, scheduler: str | None = None,
                  workers: int | None = None) -> list[ContactPoint]:
    stop = stop if stop is not None else system.stop
    if stop is None:
        raise HarnessError(f"{system.name} defines no stop time: give --stop")
    reference = contact_reference(system, stop)
    jobs = [(system, run, stop, repeats, reference) for run in masters(interval, quick)]
    return run_sweep(measure, jobs, scheduler, workers)


def steps_at(points: list[ContactPoint], target: float = TARGET) -> float:
    """Macro steps of one master at the error `target`, interpolated in log-log between the two runs that
    bracket it; nan where none do."""
    measured = sorted((p.macro_steps, p.error) for p in points if math.isfinite(p.error) and p.error > 0)
    for (s0, e0), (s1, e1) in zip(measured, measured[1:]):
        if e0 >= target >= e1:
            return s0 * (target / e0) ** (math.log(s1 / s0) / math.log(e1 / e0))
    return math.nan


def steps_needed(points: list[ContactPoint], target: float = TARGET) -> dict[str, float]:
    """Each master's macro steps at the error `target`."""
    names = list(dict.fromkeys(p.master for p in points))
    return {name: steps_at([p for p in points if p.master == name], target) for name in names}


def write_csv(points: list[ContactPoint], path: Path) -> None:
    write_records(points, path, columns_of(ContactPoint))


def read_csv(path: Path) -> list[ContactPoint]:
    return read_records(path, ContactPoint)
