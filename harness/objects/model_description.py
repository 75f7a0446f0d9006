"""The FMI 2.0 model description of an object, from its object file.

Layout (the framework relies on it, and tools/fmu_codegen.py checks it): Real value references
dense from 0 with the states first (coordinates, then velocities), their derivatives next, then
parameters in file order (with the framework's d, h and tol where the file restates them, else
appended), force inputs, point outputs, E_kin, E_pot, E; then the Integers: solver, model (when the
object has a linear model), the counters of harness.fmi.methods.COUNTERS.

ModelStructure lists what each output, state derivative and initial unknown depends on
(harness.objects.dependencies), so that an importer sees which outputs feed through from inputs.
"""
from __future__ import annotations

import re
import uuid
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

from harness.fmi.methods import COUNTERS, GBS_COLUMNS, METHODS, SOLVERS, TAYLOR_DEFAULT_ORDER, TAYLOR_ORDERS
from harness.objects.dependencies import dependencies
from harness.objects.derivation import Derivation
from harness.objects.object_file import EVENT_COUNTER, ObjectFileError

# What an importer compiles (SourceFiles): one translation unit per FMI version, which includes the rest.
SOURCE_FILES = ("fmu_fmi2.c",)
BASE = {"m": {"m": 1}, "kg": {"kg": 1}, "s": {"s": 1}, "rad": {"rad": 1}, "N": {"kg": 1, "m": 1, "s": -2},
        "J": {"kg": 1, "m": 2, "s": -2}, "W": {"kg": 1, "m": 2, "s": -3}, "Hz": {"s": -1}, "1": {},
        "deg": {"rad": 1}, "A": {"A": 1}, "K": {"K": 1}}
FACTOR = {"deg": 0.017453292519943295}
GUID_NAMESPACE = uuid.UUID("6f1c2a4e-4be1-4a53-9d2e-7d0a7c3e5b11")


def base_units(unit: str) -> tuple[dict[str, int], float]:
    """'kg.m2', 'N/m', 'm/s2', '1/s' -> SI base exponents and factor; ValueError when unknown."""
    exponents: dict[str, int] = {}
    factor = 1.0
    numerator, _, denominator = unit.partition("/")
    for part, sign in ((numerator, 1), (denominator, -1)):
        if not part:
            continue
        for token in part.split("."):
            match = re.fullmatch(r"([A-Za-z]+|1)(-?\d+)?", token)
            if not match or match.group(1) not in BASE:
                raise ValueError(token)
            power = int(match.group(2) or 1) * sign
            for base, exponent in BASE[match.group(1)].items():
                exponents[base] = exponents.get(base, 0) + exponent * power
            factor *= FACTOR.get(match.group(1), 1.0) ** power
    return {k: v for k, v in exponents.items() if v}, factor


def rate_unit(unit: str, order: int = 1) -> str:
    """The unit of a quantity's order-th time derivative: 'm' -> 'm/s', 'm/s2'; 'N/m' -> 'N/m.s-1'."""
    if not unit:
        return ""
    seconds = "s" if order == 1 else f"s{order}"
    if unit == "1":
        return f"1/{seconds}"
    return f"{unit}/{seconds}" if "/" not in unit else f"{unit}.s-{order}"


def velocity_unit(unit: str) -> str:
    return rate_unit(unit, 1)


def acceleration_unit(unit: str) -> str:
    return rate_unit(unit, 2)


@dataclass
class Variable:
    name: str
    causality: str
    variability: str
    type: str = "Real"
    initial: str | None = None
    start: float | int | None = None
    unit: str = ""
    min: float | None = None
    max: float | None = None
    description: str = ""
    derivative: int | None = None     # 1-based index of the state
    declared_type: str = ""


def variables(derivation: Derivation) -> list[Variable]:
    spec = derivation.spec
    result: list[Variable] = []
    for c in spec.coordinates:
        result.append(Variable(c.name, "output", "continuous", initial="exact", start=c.start, unit=c.unit,
                               description=c.description or f"generalized coordinate {c.name}"))
    for c in spec.coordinates:
        result.append(Variable(c.velocity, "output", "continuous", initial="exact", start=c.velocity_start,
                               unit=velocity_unit(c.unit), description=c.velocity_description or f"d{c.name}/dt"))
    n = len(spec.coordinates)
    for k, c in enumerate(spec.coordinates):
        result.append(Variable(f"der({c.name})", "local", "continuous", initial="calculated",
                               unit=velocity_unit(c.unit), derivative=k + 1))
    for k, c in enumerate(spec.coordinates):
        result.append(Variable(f"der({c.velocity})", "local", "continuous", initial="calculated",
                               unit=acceleration_unit(c.unit), derivative=n + k + 1))
    for p in spec.parameters:
        tunable = p.name in ("h", "tol")
        result.append(Variable(p.name, "parameter", "tunable" if tunable else "fixed", start=p.start, unit=p.unit,
                               min=p.min, max=p.max, description=p.description))
    points = {pt.name: pt for pt in spec.points}
    for force in spec.forces:
        for axis, name in force.inputs.items():
            what = force.description or f"external force on {force.point}"
            result.append(Variable(name, "input", "continuous", start=0.0, unit="N", description=f"{what}, {axis}"))
    for point in spec.points:
        what = point.description or point.name
        for kind, name in point.outputs.items():
            velocity = kind.startswith("v_")
            result.append(Variable(name, "output", "continuous", initial="calculated", unit="m/s" if velocity else "m",
                                   description=f"{what}, {'velocity' if velocity else 'position'} {kind[-1]}"))
    del points
    result += [Variable("E_kin", "output", "continuous", initial="calculated", unit="J",
                        description="kinetic energy T"),
               Variable("E_pot", "output", "continuous", initial="calculated", unit="J",
                        description="potential energy U"),
               Variable("E", "output", "continuous", initial="calculated", unit="J", description="total energy T + U")]
    for constraint in spec.constraints:
        gap, force = constraint.outputs
        what = constraint.description or f"constraint {constraint.name}"
        result.append(Variable(gap, "output", "continuous", initial="calculated", unit=constraint.unit,
                               description=f"{what}: its gap "
                                           f"{'(kept at 0)' if constraint.bilateral else '(>= 0 apart)'}"))
        law = "its compliant law's force" if constraint.compliant else "its force lambda"
        result.append(Variable(force, "output", "continuous", initial="calculated", unit=constraint.force_unit,
                               description=f"{what}: {law} along the gap's gradient"
                                           f"{'' if constraint.bilateral else ' (>= 0: it only pushes)'}"))
        result.append(Variable(constraint.indicator, "local", "continuous", initial="calculated",
                               description=f"{what}: its event indicator (the gap while open, the force while it "
                                           f"rests or is taut, 1 for a bilateral constraint); an event where it "
                                           f"changes sign"))
    result.append(Variable("solver", "parameter", "tunable", type="Enumeration", declared_type="Solver",
                           start=SOLVERS.index("rk4") + 1,
                           description="integration method of the Co-Simulation step; Model Exchange leaves the "
                                       "integration to the importer, where this and h, tol, taylor_order and "
                                       "gbs_columns have no effect"))
    if derivation.linear is not None:
        result.append(Variable("model", "parameter", "fixed", type="Enumeration", declared_type="Model", start=1,
                               description="nonlinear, or the quadratic approximation of T and U about rest solved "
                                           "in closed form per step"))
    result += [Variable(name, "output", "discrete", type="Integer", initial="calculated", description=description)
               for name, description in COUNTERS]
    if spec.constraints:
        result.append(Variable(EVENT_COUNTER, "output", "discrete", type="Integer", initial="calculated",
                               description="events since initialization: impacts (one per contact that receives an "
                                           "impulse), activations without impact, releases, and the onsets and ends "
                                           "of compliant contacts"))
    # appended after the counters, so that the older value references stay
    result.append(Variable("taylor_order", "parameter", "tunable", type="Integer", start=TAYLOR_DEFAULT_ORDER,
                           min=TAYLOR_ORDERS[0], max=TAYLOR_ORDERS[1],
                           description="order of the Taylor method (solver = taylor)"))
    result.append(Variable("gbs_columns", "parameter", "tunable", type="Integer", start=GBS_COLUMNS, min=2,
                           max=GBS_COLUMNS, description="columns k of gbs's extrapolation table: its order 2 k with "
                                                        "the fixed step h (tol = 0), its highest order with tol > 0"))
    # the object file's further outputs come last, so that every other value reference stays
    result += [Variable(o.name, "output", "continuous", initial="calculated", unit=o.unit, description=o.description)
               for o in spec.outputs]
    return result


def _number(value) -> str:
    if isinstance(value, int):
        return str(value)
    return repr(float(value)) if float(value) != int(float(value)) or abs(value) >= 1e16 else str(int(float(value)))


def unit_table(spec, variable_list: list[Variable]) -> dict[str, tuple[dict[str, int], float]]:
    """Every unit the variables use, as SI base exponents and factor (both FMI versions declare them)."""
    units: dict[str, tuple[dict[str, int], float]] = {}
    for v in variable_list:
        if v.unit and v.unit not in units:
            try:
                units[v.unit] = base_units(v.unit)
            except ValueError as error:
                raise ObjectFileError(f"{spec.path}: unit {v.unit!r} of {v.name}: {error.args[0]!r} is not a unit "
                                      f"this generator knows ({', '.join(BASE)}, with powers, '.' and '/')") from None
    return units


TOKEN = "{GUID}"  # where the GUID (FMI 2.0) or instantiation token (FMI 3.0) goes


def stamped(body: str) -> str:
    """The document with its token: a UUID made from the rest of it, so equal descriptions get equal tokens."""
    return body.replace(TOKEN, "{" + str(uuid.uuid5(GUID_NAMESPACE, body)) + "}")


def unit_lines(units: dict[str, tuple[dict[str, int], float]]) -> list[str]:
    """<UnitDefinitions> content, the same in both FMI versions."""
    lines = []
    for name, (exponents, factor) in units.items():
        attributes = "".join(f' {k}="{v}"' for k, v in sorted(exponents.items()))
        if factor != 1.0:
            attributes += f' factor="{factor!r}"'
        lines.append(f'    <Unit name={quoteattr(name)}><BaseUnit{attributes}/></Unit>')
    return lines


def enumerations(derivation: Derivation) -> list[tuple[str, list[tuple[str, int, str]]]]:
    """Each enumeration type: its name and its items (name, value, description)."""
    found = [("Solver", [(name, k + 1, description) for k, (name, _, description) in enumerate(_solver_items())])]
    if derivation.linear is not None:
        found.append(("Model", [("nonlinear", 1, "full equations, integrated by the chosen solver"),
                                ("linear", 2, "quadratic T and U about rest, solved in closed form per step")]))
    return found


def item_line(indent: str, item: tuple[str, int, str]) -> str:
    name, value, description = item
    return f'{indent}<Item name="{name}" value="{value}" description={quoteattr(description)}/>'


TRAILER_LINES = ['  <LogCategories>',
                 '    <Category name="logStatusError" description="errors: bad arguments, illegal call sequences"/>',
                 '    <Category name="logStatusWarning" description="warnings"/>',
                 '    <Category name="logStatusDiscard" description="steps that could not be completed"/>',
                 '    <Category name="logAll" description="everything"/>',
                 '  </LogCategories>',
                 '  <DefaultExperiment startTime="0" stopTime="10" stepSize="0.01"/>']


def common_attributes(v: Variable, reference: int) -> str:
    """The attributes a variable has in both FMI versions."""
    attributes = f'name={quoteattr(v.name)} valueReference="{reference}" causality="{v.causality}" ' \
                 f'variability="{v.variability}"'
    if v.initial:
        attributes += f' initial="{v.initial}"'
    if v.description:
        attributes += f" description={quoteattr(v.description)}"
    return attributes


def range_attributes(v: Variable) -> str:
    """start, min and max of a variable, where it has them."""
    return "".join(f' {key}="{_number(value)}"' for key, value in (("start", v.start), ("min", v.min), ("max", v.max))
                   if value is not None)


def model_description(derivation: Derivation) -> str:
    variable_list = variables(derivation)
    return stamped(_document(derivation, variable_list, unit_table(derivation.spec, variable_list), TOKEN))


def dependency_attribute(listed: set[str] | None, index: dict[str, int]) -> str:
    """The FMI 2.0 dependencies attribute for the knowns `listed` by name (None: not known), as 1-based
    indices. These FMUs declare no variable for time, so FMI 2.0's independent variable is implicit: it has
    no index to list, and an importer holds it known at every instant. An unknown that depends on time lists
    the states and inputs it depends on beside it (listing nothing would read as "depends on every known",
    the inputs among them, and show importers a feedthrough that is not there)."""
    if listed is None:
        return ""
    return ' dependencies="' + " ".join(str(k) for k in sorted(index[name] for name in listed - {"time"})) + '"'


def _document(derivation: Derivation, variable_list: list[Variable], units, guid: str) -> str:
    spec = derivation.spec
    sources = "".join(f'<File name="{f}"/>' for f in SOURCE_FILES)
    # the derivatives of constrained motion switch with the active constraints: not offered yet
    directional = "false" if spec.constraints else "true"
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="2.0" modelName="{spec.identifier}"',
        f'  guid="{guid}"',
        f'  description={quoteattr(spec.description)}',
        '  generationTool="pendulum-fmus harness.objects" variableNamingConvention="structured" '
        f'numberOfEventIndicators="{len(spec.constraints)}">',
        f'  <ModelExchange modelIdentifier="{spec.identifier}" canGetAndSetFMUstate="true" '
        'canSerializeFMUstate="true"',
        '    completedIntegratorStepNotNeeded="true" canNotUseMemoryManagementFunctions="false"',
        f'    providesDirectionalDerivative="{directional}">',
        f'    <SourceFiles>{sources}</SourceFiles>',
        '  </ModelExchange>',
        f'  <CoSimulation modelIdentifier="{spec.identifier}" canHandleVariableCommunicationStepSize="true"',
        '    canInterpolateInputs="true" maxOutputDerivativeOrder="1" canGetAndSetFMUstate="true"',
        f'    canSerializeFMUstate="true" canNotUseMemoryManagementFunctions="false" '
        f'providesDirectionalDerivative="{directional}">',
        f'    <SourceFiles>{sources}</SourceFiles>',
        '  </CoSimulation>',
        '  <UnitDefinitions>',
    ]
    lines += unit_lines(units)
    lines += ['  </UnitDefinitions>', '  <TypeDefinitions>']
    for type_name, items in enumerations(derivation):
        lines += [f'    <SimpleType name="{type_name}">', '      <Enumeration>']
        lines += [item_line("        ", item) for item in items]
        lines += ['      </Enumeration>', '    </SimpleType>']
    lines += ['  </TypeDefinitions>', *TRAILER_LINES,
              '  <ModelVariables>']
    reals = [v for v in variable_list if v.type == "Real"]
    integers = [v for v in variable_list if v.type != "Real"]
    for index, v in enumerate(reals + integers, start=1):
        attributes = common_attributes(v, index - 1)
        typed = ""
        if v.type == "Enumeration":
            typed = f'<Enumeration declaredType="{v.declared_type}" start="{v.start}"/>'
        elif v.type == "Integer":
            typed = f"<Integer{range_attributes(v)}/>"
        else:
            typed = "<Real"
            if v.unit:
                typed += f" unit={quoteattr(v.unit)}"
            if v.derivative:
                typed += f' derivative="{v.derivative}"'
            typed += range_attributes(v) + "/>"
        lines.append(f"    <!-- {index} --><ScalarVariable {attributes}>{typed}</ScalarVariable>")
    ordered = reals + integers
    outputs = [k for k, v in enumerate(ordered, start=1) if v.causality == "output"]
    derivatives = [k for k, v in enumerate(ordered, start=1) if v.derivative]
    calculated = [k for k, v in enumerate(ordered, start=1) if v.causality == "output" and v.initial == "calculated"]

    index = {v.name: k for k, v in enumerate(ordered, start=1)}
    running, initial = dependencies(derivation), dependencies(derivation, initial=True)

    def unknowns(indices, needs):
        return "".join(f'\n      <Unknown index="{k}"{dependency_attribute(needs.get(ordered[k - 1].name), index)}/>'
                       for k in indices) + "\n    "

    lines += ['  </ModelVariables>', '  <ModelStructure>',
              f'    <Outputs>{unknowns(outputs, running)}</Outputs>',
              f'    <Derivatives>{unknowns(derivatives, running)}</Derivatives>',
              f'    <InitialUnknowns>{unknowns(sorted(derivatives + calculated), initial)}</InitialUnknowns>',
              '  </ModelStructure>', '</fmiModelDescription>', '']
    return "\n".join(lines)


def _solver_items():
    return [(m.name, m.order, m.description) for m in METHODS]
