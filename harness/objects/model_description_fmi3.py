"""The FMI 3.0 model description of an object, from the same variable list as the FMI 2.0 one.

Value references are those of FMI 2.0 (the C tables serve both versions): the Float64 variables
dense from 0 in the FMI 2.0 order, then the enumerations and the counters, then the independent
variable `time`, which FMI 3.0 declares and FMI 2.0 does not. The counters are UInt64.

ModelStructure gives the dependencies of every output and state derivative on the knowns (the
continuous states, the inputs and time), from the free symbols of the derivation's expressions;
within a block of coupled coordinates of the mass matrix every acceleration is taken to depend on
everything that any row of the block depends on (the inverse mixes them). Initial unknowns carry no
dependency list (they depend on every known, as the standard says of an absent list).
"""
from __future__ import annotations

from xml.sax.saxutils import quoteattr

import sympy as sp

from harness.objects.derivation import Derivation
from harness.objects.model_description import (TOKEN, TRAILER_LINES, Variable, common_attributes, enumerations,
                                               item_line, range_attributes, stamped, unit_lines, unit_table,
                                               variables)


def value_references(variable_list: list[Variable]) -> dict[str, int]:
    """Name -> value reference, as in the FMI 2.0 description (Reals first), then time."""
    ordered = [v for v in variable_list if v.type == "Real"] + [v for v in variable_list if v.type != "Real"]
    references = {v.name: k for k, v in enumerate(ordered)}
    references["time"] = len(ordered)
    return references


def dependencies(derivation: Derivation) -> dict[str, set[str]]:
    """For each output and state derivative: the names of the knowns it depends on."""
    spec = derivation.spec
    q, v = list(spec.q), list(spec.v)
    known = {symbol: str(symbol) for symbol in q + v + list(derivation.inputs)}
    known[spec.time] = "time"

    def of(*expressions) -> set[str]:
        found: set[str] = set()
        for expression in expressions:
            found |= {known[s] for s in sp.sympify(expression).free_symbols if s in known}
        return found

    result: dict[str, set[str]] = {}
    for c, velocity in zip(spec.coordinates, v):
        result[f"der({c.name})"] = {str(velocity)}
    for block in _coupled_blocks(derivation.M):
        needs = of(*(derivation.M[i, j] for i in block for j in range(derivation.n)),
                   *(derivation.f[i] for i in block), *(derivation.Q[i] for i in block))
        needs |= {str(v[i]) for i in block}  # damping acts on each coordinate's own velocity
        for i in block:
            result[f"der({spec.coordinates[i].velocity})"] = needs
    for c, coordinate, velocity in zip(spec.coordinates, q, v):
        result[c.name] = {str(coordinate)}
        result[c.velocity] = {str(velocity)}
    for point, position, velocity in zip(spec.points, derivation.positions, derivation.velocities):
        for kind, name in point.outputs.items():
            axis = "xyz".index(kind[-1])
            result[name] = of(velocity[axis] if kind.startswith("v_") else position[axis])
    result["E_kin"], result["E_pot"] = of(derivation.T), of(derivation.U)
    result["E"] = result["E_kin"] | result["E_pot"]
    for counter in ("n_rhs", "n_steps", "n_rejected"):
        result[counter] = set()
    return result


def _coupled_blocks(M: sp.Matrix) -> list[list[int]]:
    """Groups of coordinates joined by non-zero off-diagonal entries of the mass matrix."""
    n = M.shape[0]
    group = list(range(n))

    def root(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i
    for i in range(n):
        for j in range(i + 1, n):
            if sp.simplify(M[i, j]) != 0:
                group[root(j)] = root(i)
    blocks: dict[int, list[int]] = {}
    for i in range(n):
        blocks.setdefault(root(i), []).append(i)
    return list(blocks.values())


def model_description_fmi3(derivation: Derivation) -> str:
    variable_list = variables(derivation)
    return stamped(_document(derivation, variable_list, unit_table(derivation.spec, variable_list), TOKEN))


def _document(derivation: Derivation, variable_list: list[Variable], units, token: str) -> str:
    spec = derivation.spec
    references = value_references(variable_list)
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="3.0" modelName="{spec.identifier}"',
        f'  instantiationToken="{token}"',
        f'  description={quoteattr(spec.description)}',
        '  generationTool="pendulum-fmus harness.objects" variableNamingConvention="structured">',
        f'  <ModelExchange modelIdentifier="{spec.identifier}" canGetAndSetFMUState="true" '
        'canSerializeFMUState="true" needsCompletedIntegratorStep="false"/>',
        f'  <CoSimulation modelIdentifier="{spec.identifier}" canGetAndSetFMUState="true" canSerializeFMUState="true"',
        '    canHandleVariableCommunicationStepSize="true" maxOutputDerivativeOrder="1"/>',
        '  <UnitDefinitions>', *unit_lines(units), '  </UnitDefinitions>', '  <TypeDefinitions>']
    for type_name, items in enumerations(derivation):
        lines += [f'    <EnumerationType name="{type_name}">', *(item_line("      ", item) for item in items),
                  '    </EnumerationType>']
    lines += ['  </TypeDefinitions>', *TRAILER_LINES, '  <ModelVariables>',
              f'    <Float64 name="time" valueReference="{references["time"]}" causality="independent" '
              'variability="continuous" unit="s" description="simulation time"/>']
    ordered = sorted(variable_list, key=lambda v: references[v.name])
    for v in ordered:
        attributes = common_attributes(v, references[v.name])
        if v.type == "Enumeration":
            lines.append(f'    <Enumeration {attributes} declaredType="{v.declared_type}" start="{v.start}"/>')
        elif v.type == "Integer":
            lines.append(f"    <UInt64 {attributes}/>")
        else:
            if v.unit:
                attributes += f" unit={quoteattr(v.unit)}"
            attributes += range_attributes(v)
            if v.derivative:
                state = ordered[v.derivative - 1]
                attributes += f' derivative="{references[state.name]}"'
            lines.append(f"    <Float64 {attributes}/>")
    needs = dependencies(derivation)

    def unknown(element: str, v: Variable, with_dependencies: bool = True) -> str:
        listed = ""
        if with_dependencies:
            listed = ' dependencies="' + " ".join(str(r) for r in sorted(references[n] for n in needs[v.name])) + '"'
        return f'    <{element} valueReference="{references[v.name]}"{listed}/>'
    lines += ['  </ModelVariables>', '  <ModelStructure>']
    lines += [unknown("Output", v) for v in ordered if v.causality == "output"]
    lines += [unknown("ContinuousStateDerivative", v) for v in ordered if v.derivative]
    lines += [unknown("InitialUnknown", v, False) for v in ordered
              if v.derivative or (v.causality == "output" and v.initial == "calculated")]
    lines += ['  </ModelStructure>', '</fmiModelDescription>', '']
    return "\n".join(lines)
