"""The FMI 3.0 model description of an FMU: a translation of its FMI 2.0 description.

Both versions' binaries are compiled from the same C tables, so the FMI 3.0 description is the
FMI 2.0 one in FMI 3.0's terms: the same variables, value references, units, ranges and
instantiation token (the FMI 2.0 GUID), Float64 for Real, UInt64 for the Integer outputs (the
counters), Enumeration for enumerations, and the independent variable `time`, which FMI 3.0 declares
and FMI 2.0 does not, at the next free value reference.

ModelStructure lists the dependencies of every output, state derivative and initial unknown as value
references: an object's from its derivation (harness.objects.dependencies), time included, which
FMI 2.0 cannot name; a hand-written model's (the Spring's) translated from its FMI 2.0 indices.
"""
from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from xml.sax.saxutils import quoteattr

from harness.objects.dependencies import dependencies
from harness.objects.derivation import Derivation
from harness.objects.model_description import model_description

# The FMI 2.0 <ScalarVariable> attributes FMI 3.0 keeps as they are, in this order.
_KEPT = ("name", "valueReference", "causality", "variability", "initial", "description")
_TYPED = ("declaredType", "unit", "start", "min", "max")


def model_description_fmi3(derivation: Derivation, fmi2_text: str | None = None) -> str:
    """The object's FMI 3.0 description (from its FMI 2.0 one, given or made here)."""
    return from_fmi2(fmi2_text if fmi2_text is not None else model_description(derivation), dependencies(derivation),
                     dependencies(derivation, initial=True), [c.indicator for c in derivation.spec.constraints])


def from_fmi2(fmi2_text: str, needs: dict[str, set[str]] | None = None,
              initial_needs: dict[str, set[str]] | None = None, event_indicators: list[str] = ()) -> str:
    """The FMI 3.0 description of the FMU that `fmi2_text` describes. `needs` and `initial_needs` give,
    by name, the knowns ("time" for time) each output and state derivative depends on, and each initial
    unknown; where they are None, the FMI 2.0 description's own dependency lists are translated.
    `event_indicators` names the variables of the event indicators, in their order; where it is empty, they
    are the variables named `*_indicator`, as many as the description declares (a hand-written model's)."""
    root = ET.fromstring(fmi2_text)
    cs, me = root.find("CoSimulation"), root.find("ModelExchange")
    identifier = (cs if cs is not None else me).get("modelIdentifier")
    scalars = root.find("ModelVariables").findall("ScalarVariable")
    references = {v.get("name"): int(v.get("valueReference")) for v in scalars}
    declared = int(root.get("numberOfEventIndicators", "0"))
    if not event_indicators:
        event_indicators = [name for name in references if name.endswith("_indicator")]
    if len(event_indicators) != declared:
        raise ValueError(f"{identifier}: numberOfEventIndicators is {declared}, but the description names "
                         f"{len(event_indicators)} event indicator variables ({', '.join(event_indicators) or 'none'})")
    time_reference = max(references.values()) + 1
    references["time"] = time_reference
    by_index = {k: v for k, v in enumerate(scalars, start=1)}
    # partial derivatives where FMI 2.0 offers them (not for constrained motion)
    partial = "true" if (cs if cs is not None else me).get("providesDirectionalDerivative") == "true" else "false"
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="3.0" modelName={quoteattr(root.get("modelName"))}',
        f'  instantiationToken={quoteattr(root.get("guid"))}',
        f'  description={quoteattr(root.get("description", ""))}',
        f'  generationTool={quoteattr(root.get("generationTool", ""))} variableNamingConvention="structured">',
        f'  <ModelExchange modelIdentifier="{identifier}" canGetAndSetFMUState="true" '
        'canSerializeFMUState="true" needsCompletedIntegratorStep="false"',
        f'    providesDirectionalDerivatives="{partial}" providesAdjointDerivatives="{partial}"/>',
        f'  <CoSimulation modelIdentifier="{identifier}" canGetAndSetFMUState="true" canSerializeFMUState="true"',
        '    canHandleVariableCommunicationStepSize="true" maxOutputDerivativeOrder="1" '
        'providesIntermediateUpdate="true"',
        f'    providesDirectionalDerivatives="{partial}" providesAdjointDerivatives="{partial}"/>']
    lines += _copied(root.find("UnitDefinitions"))
    types = root.find("TypeDefinitions")
    if types is not None and len(types):
        lines.append('  <TypeDefinitions>')
        for simple in types:
            lines.append(f'    <EnumerationType name={quoteattr(simple.get("name"))}>')
            for item in simple.find("Enumeration"):
                lines.append("      <Item" + _attributes(item, ("name", "value", "description")) + "/>")
            lines.append('    </EnumerationType>')
        lines.append('  </TypeDefinitions>')
    for section in ("LogCategories", "DefaultExperiment"):
        lines += _copied(root.find(section))
    lines += ['  <ModelVariables>',
              f'    <Float64 name="time" valueReference="{time_reference}" causality="independent" '
              'variability="continuous" unit="s" description="simulation time"/>']
    for v in sorted(scalars, key=lambda v: int(v.get("valueReference"))):
        typed = v[0]
        attributes = _attributes(v, _KEPT) + _attributes(typed, _TYPED)
        if typed.tag == "Real":
            if typed.get("derivative"):
                state = by_index[int(typed.get("derivative"))]
                attributes += f' derivative="{state.get("valueReference")}"'
            if v.get("causality") in ("output", "input"):  # outputs reported at steps, inputs asked for
                attributes += ' intermediateUpdate="true"'
            lines.append(f"    <Float64{attributes}/>")
        elif typed.tag == "Enumeration":
            lines.append(f"    <Enumeration{attributes}/>")
        elif v.get("causality") == "output":  # the Integer outputs count: never negative, may pass 2^31
            lines.append(f"    <UInt64{attributes}/>")
        else:  # an Integer parameter (taylor_order, gbs_columns): Int64, set and got like the enumerations
            lines.append(f"    <Int64{attributes}/>")
    lines += ['  </ModelVariables>', '  <ModelStructure>']
    structure = root.find("ModelStructure")

    def unknowns(section: str, element: str, given: dict[str, set[str]] | None) -> list[str]:
        found = []
        listing = structure.find(section)
        for unknown in listing if listing is not None else []:
            v = by_index[int(unknown.get("index"))]
            if given is not None:
                names = given.get(v.get("name"))
            elif unknown.get("dependencies") is not None:
                names = {by_index[int(k)].get("name") for k in unknown.get("dependencies").split()}
            else:
                names = None
            listed = "" if names is None else \
                ' dependencies="' + " ".join(str(r) for r in sorted(references[n] for n in names)) + '"'
            found.append(f'    <{element} valueReference="{v.get("valueReference")}"{listed}/>')
        return found
    lines += unknowns("Outputs", "Output", needs) + unknowns("Derivatives", "ContinuousStateDerivative", needs)
    lines += unknowns("InitialUnknowns", "InitialUnknown", initial_needs)
    lines += [f'    <EventIndicator valueReference="{references[name]}"/>' for name in event_indicators]
    lines += ['  </ModelStructure>', '</fmiModelDescription>', '']
    return "\n".join(lines)


def _attributes(element: ET.Element, names: tuple[str, ...]) -> str:
    return "".join(f" {name}={quoteattr(element.get(name))}" for name in names if element.get(name) is not None)


def _copied(element: ET.Element | None) -> list[str]:
    """A section both versions write alike, as it stands."""
    if element is None:
        return []
    ET.indent(element, space="  ", level=1)
    return ["  " + ET.tostring(element, encoding="unicode").rstrip()]


def build_description(identifier: str, sources: tuple[str, ...] | list[str]) -> str:
    """sources/buildDescription.xml: how an importer compiles the binary from the FMU's sources (C99,
    linked with the math library)."""
    files = "".join(f'      <SourceFile name={quoteattr(name)}/>\n' for name in sources)
    return ('<?xml version="1.0" encoding="UTF-8"?>\n<fmiBuildDescription fmiVersion="3.0">\n'
            f'  <BuildConfiguration modelIdentifier={quoteattr(identifier)}>\n    <SourceFileSet language="C99">\n'
            f'{files}    </SourceFileSet>\n    <Library name="m"/>\n  </BuildConfiguration>\n</fmiBuildDescription>\n')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Write the FMI 3.0 description of an FMU from its FMI 2.0 one, "
                                                 "or (--build-description) its sources' build description.")
    parser.add_argument("fmi2", type=Path, nargs="?")
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--build-description", nargs="+", metavar=("IDENTIFIER", "SOURCE"))
    args = parser.parse_args(argv)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    if args.build_description:
        args.out.write_text(build_description(args.build_description[0], args.build_description[1:]))
    else:
        args.out.write_text(from_fmi2(args.fmi2.read_text()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
