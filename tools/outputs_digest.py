"""Digests of what every built FMU does: for each FMU, FMI version and method, and for the calls that must
fail, the bits of every variable after every communication step, each call's status and every log message.
A change meant to keep behaviour (a redesign of the C core) is checked by two runs, before and after:

    python tools/outputs_digest.py > before.txt      (at the old commit, its build)
    python tools/outputs_digest.py > after.txt       (at the new one)
    diff before.txt after.txt                        (no line: the same bits, statuses and messages)

One line per case: its name and the SHA-256 of its record. Runs the x86_64 Linux binaries in build/.
"""
from __future__ import annotations

import argparse
import ctypes
import hashlib
import struct
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from harness.fmi.fmu_instance import AskedInputs, FmuInstance  # noqa: E402
from harness.fmi.fmus import FMU_NAMES, build_dir  # noqa: E402
from harness.fmi.methods import METHODS  # noqa: E402

STOP, STEP = 2.0, 0.05


@dataclass(frozen=True)
class Case:
    """One run: its settings (start values by name) and how it steps."""
    name: str
    settings: dict
    step: float = STEP
    stop: float = STOP
    early_return: bool = False
    reporting: bool = False


def cases_for(names: set[str]) -> Iterator[Case]:
    """Every method at its defaults (adaptive ones at a tolerance), then the settings each refusal needs."""
    for method in METHODS:
        settings = {"solver": method.name}
        if method.name in ("rkf45", "gbs", "taylor"):
            settings["tol"] = 1e-7
        yield Case(method.name, settings)
        if method.name in ("rk4", "ab4", "abm3", "gauss_legendre4", "taylor", "rkf45", "gbs", "stormer_verlet"):
            yield Case(f"{method.name}-fine", {**settings, "h": 1e-3}, step=0.013)
    yield Case("work-bound", {"solver": "rk4", "h": 1e-9}, step=1.0)
    yield Case("rkf45-no-tol", {"solver": "rkf45", "tol": 0.0})
    yield Case("gbs-tiny-tol", {"solver": "gbs", "tol": 1e-17})
    yield Case("taylor-tight", {"solver": "taylor", "tol": 1e-16, "taylor_order": 4})


def fmi3_cases() -> Iterator[Case]:
    """FMI 3.0's own paths: a step ended early at an event, and internal steps reported as they are taken."""
    for method in ("rk4", "ab3", "abm4", "implicit_midpoint", "rkf45", "gbs", "taylor", "nystrom5"):
        settings = {"solver": method, **({"tol": 1e-7} if method in ("rkf45", "gbs", "taylor") else {})}
        yield Case(f"{method}-early", settings, early_return=True)
        yield Case(f"{method}-reported", settings, reporting=True)


class Record:
    def __init__(self):
        self.digest = hashlib.sha256()

    def add(self, *items) -> None:
        for item in items:
            if isinstance(item, float):
                self.digest.update(struct.pack("<d", item))
            else:
                self.digest.update(repr(item).encode())


def run_case(path: Path, case: Case) -> str:
    record = Record()
    reported: list[list[float]] = []
    instance, keep = open_instance(path, case, reported)
    try:
        names = [v.name for v in instance.model_description.modelVariables
                 if v.type in ("Real", "Float64", "Integer", "Int32", "Int64")
                 and v.causality in ("output", "local", "parameter")
                 and v.variability != "constant"]
        settings = {k: v for k, v in case.settings.items() if k in instance.variables}
        try:
            instance.initialize(0.0, **settings)
        except Exception as error:  # a refused setting: its message is the record
            record.add("initialize", str(error), [str(m) for m in instance.log.messages])
            return record.digest.hexdigest()
        t = 0.0
        while t < case.stop - 1e-12:
            status = instance.do_step(t, case.step)
            record.add(status, [str(m) for m in instance.log.messages])
            instance.log.messages.clear()
            if status > 1:
                record.add(instance.last_successful_time())
                break
            if case.early_return and instance.returned_early():
                t = instance.last_successful_time()
                record.add("early", t)
            else:
                t += case.step
            record.add(*instance.get(*names))
            record.add(*[x for row in reported for x in row])
            reported.clear()
    finally:
        instance.free()
        del keep
    return record.digest.hexdigest()


UPDATE = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_double, ctypes.c_bool, ctypes.c_bool, ctypes.c_bool,
                          ctypes.c_bool, ctypes.POINTER(ctypes.c_bool), ctypes.POINTER(ctypes.c_double))


def open_instance(path: Path, case: Case, reported: list) -> tuple[FmuInstance, object]:
    """The instance for a case, and what must live as long as it (the reporting callback)."""
    if not case.reporting:
        return FmuInstance(path, early_return=case.early_return), None
    holder: dict = {}

    def update(env, time, set_requested, get_allowed, finished, can_return, early, last):
        if get_allowed:
            reported.append([float(time), *holder["instance"].get(*holder["outputs"])])

    callback = UPDATE(update)
    address = ctypes.cast(callback, ctypes.c_void_p).value
    instance = FmuInstance(path, asked_inputs=AskedInputs(address, 0, ()))
    holder["instance"] = instance
    holder["outputs"] = [v.name for v in instance.model_description.modelVariables
                         if v.causality == "output" and v.type == "Float64"]
    return instance, callback


def digests(only: list[str] | None, log: Callable[[str], None]) -> Iterator[str]:
    for name in FMU_NAMES:
        if only and name not in only:
            continue
        for version, path in (("2.0", build_dir() / "fmus" / f"{name}.fmu"),
                              ("3.0", build_dir() / "fmus" / "fmi3" / f"{name}.fmu")):
            cases = list(cases_for(set()))
            if version == "3.0":
                cases += list(fmi3_cases())
            for case in cases:
                log(f"{name} {version} {case.name}")
                yield f"{name} {version} {case.name} {run_case(path, case)}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="only these FMUs")
    arguments = parser.parse_args()
    for line in digests(arguments.names, lambda text: None):
        print(line, flush=True)


if __name__ == "__main__":
    main()
