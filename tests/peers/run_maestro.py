"""Runs a system (scene file or SSP) or one FMU in Maestro 2's MaBL interpreter and prints the named
outputs after each step as JSON.

    run_maestro.py JAR {SYSTEM|FMU} STEP STEPS START_JSON WORKDIR VARIABLE...

Maestro's own specification generator (sg1 import) stops on the pendulums' Enumeration parameters
("Enumeration not supported" in its Initializer), so this writes the MaBL specification itself:
Jacobi coupling with inputs held from the previous communication point, the semantics libcosim and
ecos use. Every fmi2 status is folded into a `worst` column so that the caller can assert it is OK.
VARIABLE is `component.variable` for a system and a plain name for one FMU (component "unit").
"""
from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

from fmpy import read_model_description

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from harness.cosim.system import Component, System, load_system  # noqa: E402


class Spec:
    """MaBL text built statement by statement; every fmi2 call updates `worst`."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def add(self, line: str) -> None:
        self.lines.append(line)

    def call(self, expression: str) -> None:
        self.add(f"status = {expression};")
        self.add("if (status > worst) { worst = status; }")

    def text(self) -> str:
        return "simulation\nimport FMI2;\nimport DataWriter;\n{\n" + "\n".join(self.lines) + "\n}\n"


def real_list(values) -> str:
    return "{" + ", ".join(repr(float(v)) for v in values) + "}"


def uint_list(values) -> str:
    return "{" + ", ".join(str(int(v)) for v in values) + "}"


def write_spec(system: System, step: float, steps: int, recorded: list[tuple[str, str]]) -> str:
    descriptions = {c.name: read_model_description(str(c.fmu)) for c in system.components}
    variables = {name: {v.name: v for v in md.modelVariables} for name, md in descriptions.items()}
    spec = Spec()
    spec.add("int status = 0;\nint worst = 0;")
    headers = ", ".join(f'"{c}.{v}"' for c, v in recorded)
    spec.add(f'DataWriter writer = load("DataWriter");\nstring headers[{len(recorded) + 1}] = {{"worst", {headers}}};')
    spec.add("DataWriterConfig config = writer.writeHeader(headers);")
    for c in system.components:
        spec.add(f'FMI2 fmu_{c.name} = load("FMI2", "{descriptions[c.name].guid}", "{c.fmu.resolve()}");')
        spec.add(f'FMI2Component {c.name} = fmu_{c.name}.instantiate("{c.name}", false, false);')
    for c in system.components:
        spec.call(f"{c.name}.setupExperiment(false, 0.0, 0.0, false, 0.0)")
        reals = [(variables[c.name][k].valueReference, v) for k, v in c.start.items()
                 if variables[c.name][k].type == "Real"]
        integers = [(variables[c.name][k], v) for k, v in c.start.items() if variables[c.name][k].type != "Real"]
        if reals:
            spec.add(f"uint start_real_vr_{c.name}[{len(reals)}] = {uint_list(r for r, _ in reals)};")
            spec.add(f"real start_real_{c.name}[{len(reals)}] = {real_list(v for _, v in reals)};")
            spec.call(f"{c.name}.setReal(start_real_vr_{c.name}, {len(reals)}, start_real_{c.name})")
        if integers:
            codes = [{i.name: i.value for i in var.declaredType.items}[value] if isinstance(value, str) else value
                     for var, value in integers]
            spec.add(f"uint start_int_vr_{c.name}[{len(integers)}] = "
                     f"{uint_list(v.valueReference for v, _ in integers)};")
            spec.add(f"int start_int_{c.name}[{len(integers)}] = {uint_list(codes)};")
            spec.call(f"{c.name}.setInteger(start_int_vr_{c.name}, {len(integers)}, start_int_{c.name})")
        spec.call(f"{c.name}.enterInitializationMode()")
    # One buffer per connected output (its value at the last communication point).
    for n, link in enumerate(system.connections):
        spec.add(f"uint out_vr_{n}[1] = {{{variables[link.source][link.output].valueReference}}};")
        spec.add(f"uint in_vr_{n}[1] = {{{variables[link.target][link.input].valueReference}}};")
        spec.add(f"real held_{n}[1];")

    def exchange() -> None:
        for n, link in enumerate(system.connections):
            spec.call(f"{link.source}.getReal(out_vr_{n}, 1, held_{n})")
        for n, link in enumerate(system.connections):
            spec.call(f"{link.target}.setReal(in_vr_{n}, 1, held_{n})")

    for _ in range(len(system.components) + 1):  # settles any acyclic chain of feed-through at t = 0
        exchange()
    for c in system.components:
        spec.call(f"{c.name}.exitInitializationMode()")
    for n, (c, v) in enumerate(recorded):
        spec.add(f"uint rec_vr_{n}[1] = {{{variables[c][v].valueReference}}};\nreal rec_{n}[1];")
    spec.add(f"real time = 0.0;\nint n = 0;\nwhile (n < {steps}) {{")
    exchange()
    for c in system.components:
        spec.call(f"{c.name}.doStep(time, {step!r}, true)")
    spec.add(f"n = n + 1;\ntime = n * {step!r};")
    for n, (c, v) in enumerate(recorded):
        spec.call(f"{c}.getReal(rec_vr_{n}, 1, rec_{n})")
    spec.add("writer.writeDataPoint(config, time, worst, " + ", ".join(f"rec_{n}[0]" for n in range(len(recorded)))
             + ");\n}")
    spec.add("writer.close();")
    for c in system.components:
        spec.call(f"{c.name}.terminate()")
        spec.add(f"fmu_{c.name}.freeInstance({c.name});\nunload(fmu_{c.name});")
    spec.add("unload(writer);")
    return spec.text()


def main() -> None:
    jar, target, step, steps = sys.argv[1], Path(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
    start, workdir, names = json.loads(sys.argv[5]), Path(sys.argv[6]), sys.argv[7:]
    if target.suffix == ".fmu":
        system = System("unit", [Component("unit", target, start)], [])
        recorded = [("unit", name) for name in names]
    else:
        system = load_system(target)
        recorded = [tuple(name.split(".", 1)) for name in names]
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / "spec.mabl").write_text(write_spec(system, step, steps, recorded))
    result = subprocess.run(["java", "-jar", jar, "interpret", "spec.mabl", "-output", "out"], cwd=workdir,
                            capture_output=True, text=True, timeout=600)
    if result.returncode != 0:
        sys.exit(f"maestro failed ({result.returncode}): {(result.stdout + result.stderr)[-3000:]}")
    with open(workdir / "out" / "outputs.csv", newline="") as table:
        rows = [[float(x) for x in row[1:]] for row in list(csv.reader(table))[1:]]
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
