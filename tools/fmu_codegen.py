#!/usr/bin/env python3
"""Generate the C view of each modelDescription XML, and the FMU documentation page.

The XML in modelDescription/ is the single source of truth. This script checks the rules the C
framework relies on and writes, per FMU:

  <out>/<id>/model_description.h   value references, variable table, start values, ranges, GUID
  <out>/<id>/documentation/index.html   equations (from fmus/models/<id>/equations.html) and
                                         the variable table (from the XML)

Any rule broken is a build error, so C and XML cannot disagree. Standard library only: the build
must work on a machine that has nothing but Python and a C compiler.
"""
from __future__ import annotations

import argparse
import html
import importlib.util
import math
import re
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

INTEGER_TYPES = ("Integer", "Enumeration")
TYPE_TAGS = ("Real",) + INTEGER_TYPES + ("Boolean", "String")


class ModelDescriptionError(Exception):
    pass


@dataclass
class Variable:
    index: int  # 1-based position in ModelVariables, as ModelStructure refers to it
    name: str
    value_reference: int
    causality: str
    variability: str
    initial: str
    type_tag: str
    unit: str = ""
    declared_type: str = ""
    start: str | None = None
    min: str | None = None
    max: str | None = None
    derivative_of: int | None = None
    description: str = ""

    @property
    def c_name(self) -> str:
        return re.sub(r"[^A-Za-z0-9_]", "_", self.name).strip("_").replace("__", "_")


@dataclass
class ModelDescription:
    path: Path
    identifier: str
    guid: str
    description: str
    variables: list[Variable]
    enumerations: dict[str, list[tuple[str, int, str]]]
    source_files: list[str]
    event_indicators: int = 0
    states: list[Variable] = field(default_factory=list)


def _default_initial(causality: str, variability: str) -> str:
    if causality in ("parameter", "input") or variability == "constant":
        return "exact"
    if causality == "calculatedParameter":
        return "calculated"
    return "calculated"


def parse(path: Path) -> ModelDescription:
    root = ET.parse(path).getroot()
    if root.get("fmiVersion") != "2.0":
        raise ModelDescriptionError(f"{path}: fmiVersion must be 2.0")
    identifiers = {e.get("modelIdentifier") for e in root if e.tag in ("ModelExchange", "CoSimulation")}
    if len(identifiers) != 1:
        raise ModelDescriptionError(f"{path}: ModelExchange and CoSimulation must share one modelIdentifier")
    identifier = identifiers.pop()
    if identifier != path.stem and path.name != "modelDescription.xml":
        raise ModelDescriptionError(f"{path}: modelIdentifier {identifier} must equal the file name")
    source_lists = [[f.get("name") for f in e.iter("File")] for e in root if e.tag in ("ModelExchange", "CoSimulation")]
    if any(s != source_lists[0] for s in source_lists):
        raise ModelDescriptionError(f"{path}: ModelExchange and CoSimulation must list the same SourceFiles")

    enumerations: dict[str, list[tuple[str, int, str]]] = {}
    for simple in root.iter("SimpleType"):
        enum = simple.find("Enumeration")
        if enum is not None:
            enumerations[simple.get("name")] = [
                (item.get("name"), int(item.get("value")), item.get("description", "")) for item in enum.findall("Item")
            ]

    variables: list[Variable] = []
    for index, sv in enumerate(root.find("ModelVariables").findall("ScalarVariable"), start=1):
        typed = next(child for child in sv if child.tag in TYPE_TAGS)
        causality = sv.get("causality", "local")
        variability = sv.get("variability", "continuous")
        derivative = typed.get("derivative")
        variables.append(Variable(
            index=index, name=sv.get("name"), value_reference=int(sv.get("valueReference")),
            causality=causality, variability=variability,
            initial=sv.get("initial") or _default_initial(causality, variability),
            type_tag=typed.tag, unit=typed.get("unit", ""), declared_type=typed.get("declaredType", ""),
            start=typed.get("start"), min=typed.get("min"), max=typed.get("max"),
            derivative_of=int(derivative) if derivative else None, description=sv.get("description", ""),
        ))
    md = ModelDescription(path, identifier, root.get("guid"), root.get("description", ""), variables,
                          enumerations, source_lists[0], int(root.get("numberOfEventIndicators", "0")))
    check(md)
    return md


def check(md: ModelDescription) -> None:
    """The layout rules the C framework relies on (dense value references, states first)."""
    where = md.path.name
    reals = [v for v in md.variables if v.type_tag == "Real"]
    integers = [v for v in md.variables if v.type_tag in INTEGER_TYPES]
    others = [v for v in md.variables if v.type_tag not in ("Real",) + INTEGER_TYPES]
    if others:
        raise ModelDescriptionError(f"{where}: only Real, Integer and Enumeration variables are supported "
                                    f"({others[0].name})")
    if [v.value_reference for v in reals] != list(range(len(reals))):
        raise ModelDescriptionError(f"{where}: Real value references must be 0..{len(reals) - 1} in document order")
    base = len(reals)
    if [v.value_reference for v in integers] != list(range(base, base + len(integers))):
        raise ModelDescriptionError(f"{where}: Integer/Enumeration value references must follow the Reals, "
                                    f"{base}..{base + len(integers) - 1} in document order")
    derivatives = [v for v in md.variables if v.derivative_of is not None]
    md.states = [md.variables[v.derivative_of - 1] for v in derivatives]
    for k, (state, der) in enumerate(zip(md.states, derivatives)):
        if state.value_reference != k:
            raise ModelDescriptionError(f"{where}: state {state.name} must be Real number {k} (states come first)")
        if der.name != f"der({state.name})":
            raise ModelDescriptionError(f"{where}: {der.name} is the derivative of {state.name}; "
                                        f"name it der({state.name})")
        if der.value_reference != len(md.states) + k:
            raise ModelDescriptionError(f"{where}: {der.name} must directly follow the states, in the same order")
    for v in md.variables:
        if v.initial in ("exact", "approx") and v.start is None:
            raise ModelDescriptionError(f"{where}: {v.name} needs a start value")
        if v.type_tag == "Enumeration" and v.declared_type not in md.enumerations:
            raise ModelDescriptionError(f"{where}: {v.name} refers to unknown type {v.declared_type}")
        if v.min is not None and v.start is not None and float(v.start) < float(v.min):
            raise ModelDescriptionError(f"{where}: start of {v.name} is below its min")
        if v.max is not None and v.start is not None and float(v.start) > float(v.max):
            raise ModelDescriptionError(f"{where}: start of {v.name} is above its max")
    names = [v.name for v in md.variables]
    if len(set(names)) != len(names):
        raise ModelDescriptionError(f"{where}: variable names must be unique")
    if md.states:
        for required in ("solver", "h", "tol", "n_rhs", "n_steps", "n_rejected", "n_jacobians", "n_iterations", "d"):
            if required not in names:
                raise ModelDescriptionError(f"{where}: a model with states must declare the variable {required}")


CAUSALITY = {"parameter": "CAUSALITY_PARAMETER", "input": "CAUSALITY_INPUT", "output": "CAUSALITY_OUTPUT",
             "local": "CAUSALITY_LOCAL", "calculatedParameter": "CAUSALITY_CALCULATED_PARAMETER",
             "independent": "CAUSALITY_INDEPENDENT"}
VARIABILITY = {"constant": "VARIABILITY_CONSTANT", "fixed": "VARIABILITY_FIXED", "tunable": "VARIABILITY_TUNABLE",
               "discrete": "VARIABILITY_DISCRETE", "continuous": "VARIABILITY_CONTINUOUS"}
INITIAL = {"exact": "INITIAL_EXACT", "approx": "INITIAL_APPROX", "calculated": "INITIAL_CALCULATED"}


def _c_double(text: str | None, default: float) -> str:
    value = default if text is None else float(text)
    if math.isinf(value):
        return "INFINITY" if value > 0 else "-INFINITY"
    return repr(float(value))


def _variable_row(v: Variable, md: ModelDescription) -> str:
    low, high = v.min, v.max
    if v.type_tag == "Enumeration":
        values = [value for _, value, _ in md.enumerations[v.declared_type]]
        low = low if low is not None else str(min(values))
        high = high if high is not None else str(max(values))
    return (f'    {{"{v.name}", {CAUSALITY[v.causality]}, {VARIABILITY[v.variability]}, {INITIAL[v.initial]}, '
            f'{1 if v.start is not None else 0}, {_c_double(v.start, 0.0)}, {_c_double(low, -math.inf)}, '
            f'{_c_double(high, math.inf)}}},')


def _methods_table():
    """harness/fmi/methods.py, loaded by its path: the table of methods, without the harness's dependencies."""
    path = Path(__file__).resolve().parents[1] / "harness" / "fmi" / "methods.py"
    spec = importlib.util.spec_from_file_location("methods_table", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


def method_dispatch(md: ModelDescription) -> list[str]:
    """The framework's dispatch over the methods, from the methods table: per engine with coefficients the list
    X(SOLVER_<NAME>, <its coefficients>) that the switches in integrators.c expand, the declarations of those
    coefficients, and the adaptive test."""
    table = _methods_table()
    items = [name for name, _, _ in md.enumerations["Solver"]]
    if items != list(table.SOLVERS):
        raise ModelDescriptionError(f"{md.path}: the Solver enumeration {items} is not the methods table's "
                                    f"{list(table.SOLVERS)} (harness/fmi/methods.py)")
    lines = ["",
             "/* The methods' dispatch, from the methods table (harness/fmi/methods.py): per engine with coefficients,",
             " * X(SOLVER_<NAME>, <the C name of its coefficients in integrators.c>) for each of its methods. */"]
    for engine, spec in table.ENGINES.items():
        if spec.table is None:
            continue
        entries = " ".join(f"X(SOLVER_{m.name.upper()}, {m.c_table})" for m in table.METHODS if m.engine == engine)
        lines.append(f"#define {engine.upper()}_METHODS(X) {entries}")
    always = [m.name for m in table.METHODS if table.ENGINES[m.engine].step_control == "tol"]
    with_tol = [m.name for m in table.METHODS if table.ENGINES[m.engine].step_control == "tol or h"]
    test = " || ".join([*(f"(solver) == SOLVER_{name.upper()}" for name in always),
                        "((" + " || ".join(f"(solver) == SOLVER_{name.upper()}" for name in with_tol)
                        + ") && (tol) > 0.0)"])
    needs_tol = " || ".join(f"(solver) == SOLVER_{name.upper()}" for name in always)
    lines += ["/* Whether the method picks its own steps (at most h long) to meet tol. */",
              f"#define ADAPTIVE_METHOD(solver, tol) ({test})",
              "/* Whether the method needs tol > 0 (its steps only from tol), and those that take fixed steps at "
              "tol = 0. */",
              f"#define NEEDS_TOL(solver) ({needs_tol or '0'})",
              f'#define FIXED_STEP_AT_ZERO_TOL "{" and ".join(with_tol)}"']
    return lines


def header(md: ModelDescription, xml_name: str) -> str:
    reals = [v for v in md.variables if v.type_tag == "Real"]
    integers = [v for v in md.variables if v.type_tag in INTEGER_TYPES]
    inputs = [v for v in reals if v.causality == "input"]
    # after the states and their derivatives, the run of Reals that only a setter writes (range-checked there)
    set_begin = set_end = 2 * len(md.states)
    while set_end < len(reals) and reals[set_end].causality in ("parameter", "input"):
        set_end += 1
    lines = [
        f"/* Generated from modelDescription/{xml_name} by tools/fmu_codegen.py. Do not edit: edit the XML. */",
        "#ifndef MODEL_DESCRIPTION_H",
        "#define MODEL_DESCRIPTION_H",
        "",
        f"#define MODEL_IDENTIFIER {md.identifier}",
        f'#define MODEL_IDENTIFIER_STRING "{md.identifier}"',
        f'#define MODEL_GUID "{md.guid}"',
        f"#define N_REAL {len(reals)}",
        f"#define N_INTEGER {len(integers)}",
        f"#define INTEGER_VR_BASE {len(reals)}",
        f"#define N_STATES {len(md.states)}",
        f"#define N_INPUTS {len(inputs)}",
        f"#define N_EVENT_INDICATORS {md.event_indicators}",
        "/* Reals SET_REALS_BEGIN .. SET_REALS_END - 1 are parameters and inputs: checked when set, never computed. */",
        f"#define SET_REALS_BEGIN {set_begin}",
        f"#define SET_REALS_END {set_end}",
        "",
    ]
    lines += [f"#define VR_{v.c_name} {v.value_reference}" for v in md.variables]
    lines += [f"#define INT_{v.c_name} {v.value_reference - len(reals)}" for v in integers]
    lines.append("")
    for type_name, items in md.enumerations.items():
        lines += [f"#define {type_name.upper()}_{name.upper()} {value}" for name, value, _ in items]
        lines.append(f"#define {type_name.upper()}_COUNT {len(items)}")
    if "Solver" in md.enumerations:
        lines += method_dispatch(md)
    lines += ["", "#ifdef MODEL_DESCRIPTION_TABLES",
              "static const VariableInfo REAL_VARIABLES[N_REAL] = {"]
    lines += [_variable_row(v, md) for v in reals]
    lines.append("};")
    if integers:
        lines.append("static const VariableInfo INTEGER_VARIABLES[N_INTEGER] = {")
        lines += [_variable_row(v, md) for v in integers]
        lines.append("};")
    if inputs:
        lines.append("static const unsigned INPUT_VRS[N_INPUTS] = {"
                     + ", ".join(f"VR_{v.c_name}" for v in inputs) + "};")
    if "Solver" in md.enumerations:
        names = ", ".join(f'"{name}"' for name, _, _ in md.enumerations["Solver"])
        lines.append(f"static const char *const SOLVER_NAMES[SOLVER_COUNT] = {{{names}}};")
    lines += ["#endif", "", "#endif", ""]
    return "\n".join(lines)


def documentation(md: ModelDescription, equations_html: str) -> str:
    rows = []
    for v in md.variables:
        rows.append("<tr>" + "".join(f"<td>{html.escape(str(x))}</td>" for x in (
            v.name, v.value_reference, v.causality, v.variability, v.declared_type or v.type_tag,
            v.unit, v.start if v.start is not None else "", v.min or "", v.max or "", v.description)) + "</tr>")
    enum_blocks = []
    for type_name, items in md.enumerations.items():
        items_html = "".join(f"<li><code>{value}</code> {html.escape(name)}: {html.escape(desc)}</li>"
                             for name, value, desc in items)
        enum_blocks.append(f"<h3>{html.escape(type_name)}</h3><ul>{items_html}</ul>")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{md.identifier}</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:auto}}table{{border-collapse:collapse}}
td,th{{border:1px solid #bbb;padding:2px 6px}}code{{background:#f4f4f4}}</style></head>
<body>
<h1>{md.identifier}</h1>
<p>{html.escape(md.description)}. FMI 2.0 Co-Simulation and Model Exchange, GUID <code>{md.guid}</code>.</p>
{equations_html}
<h2>Variables</h2>
<table><tr><th>name</th><th>value reference</th><th>causality</th><th>variability</th><th>type</th><th>unit</th>
<th>start</th><th>min</th><th>max</th><th>description</th></tr>
{chr(10).join(rows)}
</table>
{''.join(enum_blocks)}
</body></html>
"""


FRAMEWORK = Path(__file__).resolve().parent.parent / "fmus" / "framework"
SINGLE_UNIT = "fmu_fmi2.c"


def check_source_files(md: ModelDescription, compiled: list[str]) -> None:
    """SourceFiles list the one translation unit, and it includes exactly the C files the build compiles."""
    if md.source_files != [SINGLE_UNIT]:
        raise ModelDescriptionError(f"{md.path.name}: SourceFiles {md.source_files} must list {SINGLE_UNIT} alone")
    included = sorted(re.findall(r'^#include "([^"]+[.]c)"', (FRAMEWORK / SINGLE_UNIT).read_text(), flags=re.M))
    if included != compiled:
        raise ModelDescriptionError(f"{md.path.name}: SourceFiles' {SINGLE_UNIT} includes {included}, "
                                    f"the build compiles {compiled}")


def _shared_guids(descriptions: list) -> list[str]:
    """The files of the first GUID that two or more of the descriptions carry; none when each is unique."""
    by_guid: dict[str, list[str]] = {}
    for md in descriptions:
        by_guid.setdefault(md.guid, []).append(str(md.path))
    return next((paths for paths in by_guid.values() if len(paths) > 1), [])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="output folder (one subfolder per FMU)")
    parser.add_argument("--models", type=Path, help="fmus/models (equations.html per model)")
    parser.add_argument("--unique-guids", action="store_true",
                        help="only check that no two of the files share a GUID (the build generates each FMU alone)")
    parser.add_argument("--sources", nargs="*", default=[], help="file names the build packs into sources/")
    parser.add_argument("--xml", nargs="+", type=Path, required=True, help="modelDescription files")
    args = parser.parse_args(argv)
    if not args.unique_guids and (args.out is None or args.models is None):
        parser.error("--out and --models are needed to generate")
    try:
        descriptions = [parse(path) for path in args.xml]
        shared = _shared_guids(descriptions)
        if shared:
            raise ModelDescriptionError(f"{' and '.join(shared)} share a GUID")
        for md in descriptions if not args.unique_guids else []:
            if args.sources:
                check_source_files(md, sorted(s for s in args.sources if s.endswith(".c")))
            target = args.out / md.identifier
            (target / "documentation").mkdir(parents=True, exist_ok=True)
            # Written also when unchanged: an output older than its inputs would make make rerun this.
            (target / "model_description.h").write_text(header(md, md.path.name))
            beside = md.path.parent / "equations.html"  # a generated model description has its equations beside it
            equations = (beside if beside.is_file() else args.models / md.identifier / "equations.html").read_text()
            (target / "documentation" / "index.html").write_text(documentation(md, equations))
    except (ModelDescriptionError, ET.ParseError, OSError, ValueError, StopIteration) as error:
        print(f"fmu_codegen: error: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
