#!/usr/bin/env python3
"""Agreement of the generated thesis pendulums with the hand-written FMUs they replaced.

Builds the hand-written SimplePendulum, DoublePendulum and SpringPendulum FMUs from commit ffbd2d8
(the last one before the physics was generated) in a temporary directory, runs each of them and
the current FMU (build/fmus/<id>.fmu) with every solver from the same start values (and the
SimplePendulum also with model = linear), and prints the largest absolute difference in every
state over the run, read at every 0.01 s output point.
"""
from __future__ import annotations

import argparse
import io
import shutil
import subprocess
import sys
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fmpy import extract, read_model_description  # noqa: E402

from harness.fmi.fmu_instance import OK, FmuInstance  # noqa: E402
from harness.fmi.fmus import build_dir, build_fmus  # noqa: E402
from harness.fmi.methods import SOLVERS  # noqa: E402

HANDWRITTEN_COMMIT = "ffbd2d8"
OUTPUT_STEP = 0.01
# Long enough for the methods' differences in rounding to grow, short enough that the double
# pendulum, which is chaotic, does not amplify them beyond meaning.
DURATION = {"SimplePendulum": 10.0, "DoublePendulum": 2.0, "SpringPendulum": 10.0}


@dataclass(frozen=True)
class Case:
    model: str
    label: str                      # the solver, or "linear" for the closed form
    settings: dict[str, str]        # start values set before initialization


def cases() -> list[Case]:
    result = []
    for model in DURATION:
        # the methods the hand-written FMUs had (the symmetric ones came later)
        result += [Case(model, solver, {"solver": solver}) for solver in SOLVERS[:SOLVERS.index("ab6") + 1]]
        if model == "SimplePendulum":
            result.append(Case(model, "linear", {"model": "linear"}))
    return result


def history_unavailable() -> str | None:
    """Why the hand-written FMUs cannot be rebuilt from git history, or None when they can."""
    if shutil.which("git") is None:
        return "git is not installed"
    if shutil.which("cmake") is None:
        return "cmake is not installed"
    if subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--git-dir"], capture_output=True).returncode != 0:
        return f"{ROOT} is not a git checkout"
    probe = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", "--quiet",
                            f"{HANDWRITTEN_COMMIT}^{{commit}}"], capture_output=True)
    if probe.returncode != 0:
        return f"commit {HANDWRITTEN_COMMIT} is not in this checkout's git history (a shallow clone or an export)"
    return None


def build_handwritten(folder: Path) -> Path:
    """Extracts the commit into folder/src and builds its three pendulum FMUs; returns their folder."""
    source = folder / "src"
    source.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", HANDWRITTEN_COMMIT],
                             check=True, capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        if hasattr(tarfile, "data_filter"):
            tar.extractall(source, filter="data")
        else:
            tar.extractall(source)
    build = source / "build"
    steps = [["cmake", "-S", str(source), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
              f"-DPython3_EXECUTABLE={sys.executable}"],
             ["cmake", "--build", str(build), "-j2", "--target", *(f"{model}_fmu" for model in DURATION)]]
    for command in steps:
        result = subprocess.run(command, capture_output=True, text=True)
        if result.returncode != 0:
            tail = "\n".join((result.stdout + result.stderr).strip().splitlines()[-20:])
            raise SystemExit(f"building the hand-written FMUs of {HANDWRITTEN_COMMIT} failed: "
                             f"{' '.join(command)}\n{tail}")
    return build / "fmus"


def state_names(fmu: Path) -> list[str]:
    return [v.derivative.name for v in read_model_description(str(fmu)).modelVariables if v.derivative is not None]


def trajectory(fmu: Path, unzipped: str, case: Case, states: list[str]) -> tuple[list[list[float]], str]:
    """The states at every output point; the second value says where a run stopped early ("" if not)."""
    rows = []
    steps = round(DURATION[case.model] / OUTPUT_STEP)
    with FmuInstance(fmu, unzipdir=unzipped) as instance:
        instance.initialize(**case.settings)
        rows.append(instance.get(*states))
        for k in range(steps):
            status = instance.do_step(k * OUTPUT_STEP, OUTPUT_STEP)
            if status != OK:
                return rows, f"status {status} at t = {k * OUTPUT_STEP:g}: {instance.last_message()}"
            rows.append(instance.get(*states))
    return rows, ""


def agreement() -> int:
    reason = history_unavailable()
    if reason is not None:
        print(f"agreement with the hand-written FMUs skipped: {reason}")
        return 0
    build_fmus()
    with tempfile.TemporaryDirectory(prefix="handwritten-fmus-") as temporary:
        folder = Path(temporary)
        old_fmus = build_handwritten(folder)
        # Each FMU unzipped once, inside the temporary directory, so that nothing is left behind.
        unzipped: dict[tuple[str, str], tuple[Path, str]] = {}
        for model in DURATION:
            for side, fmu in (("old", old_fmus / f"{model}.fmu"), ("new", build_dir() / "fmus" / f"{model}.fmu")):
                unzipped[model, side] = fmu, extract(str(fmu), unzipdir=str(folder / f"{model}-{side}"))

        print(f"Largest |generated - hand-written ({HANDWRITTEN_COMMIT})| over the run, at every {OUTPUT_STEP:g} s "
              "output point, per state")
        worst: dict[str, float] = {}
        current_model = ""
        for case in cases():
            new_fmu, new_dir = unzipped[case.model, "new"]
            old_fmu, old_dir = unzipped[case.model, "old"]
            states = state_names(new_fmu)
            if case.model != current_model:
                current_model = case.model
                print(f"\n{case.model} ({DURATION[case.model]:g} s)")
                print(f"  {'method':9s}" + "".join(f" {name:>10s}" for name in states))
            new_rows, new_stop = trajectory(new_fmu, new_dir, case, states)
            old_rows, old_stop = trajectory(old_fmu, old_dir, case, states)
            largest = [max(abs(a[i] - b[i]) for a, b in zip(new_rows, old_rows)) for i in range(len(states))]
            if len(new_rows) != len(old_rows) or new_stop != old_stop:
                largest = [float("inf")] * len(states)  # one stopped where the other did not
            worst[case.model] = max(worst.get(case.model, 0.0), *largest)
            note = ""
            if new_stop or old_stop:
                note = f"   stopped: generated {new_stop or 'no'}; hand-written {old_stop or 'no'}"
            print(f"  {case.label:9s}" + "".join(f" {value:10.3g}" for value in largest) + note)

        print("\nLargest difference per object, every method and state:")
        for model, value in worst.items():
            print(f"  {model:16s} {value:.3g}" + ("   (bit-identical)" if value == 0.0 else ""))
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.parse_args()
    return agreement()


if __name__ == "__main__":
    sys.exit(main())
