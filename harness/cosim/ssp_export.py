"""Any system written back as an SSP 1.0 archive (`harness export SCENE --ssp FILE`), so that other
importers (libcosim, ecos, Maestro) run the same scene: `SystemStructure.ssd` and every FMU the
system uses under `resources/`.

* A component's start values become an inline parameter set named "initialValues": floats as Real,
  enumeration items as Integer with the item's value (every importer here takes that; not all of
  them read items by name), other integers as Integer, Booleans as Boolean.
* Connectors: every variable a connection uses, inputs and outputs, typed Real.
* The stop time goes into DefaultExperiment. The communication step, the power bonds and how the
  scene is looked at (the camera, the traces, the description), for which SSP 1.0 has no element, go
  into annotations of the system ("org.pendulum-harness.step", "org.pendulum-harness.bonds" and
  "org.pendulum-harness.view"), which `load_ssp` reads back and other importers ignore.
* The step also goes where other importers read one, so that they run the scene at its step.
  OMSimulator: the system's first annotation, "org.openmodelica", holds oms:Annotations/
  oms:SimulationInformation. Its C++ reader (2.x, src/OMSimulatorLib/System.cpp and SystemWC.cpp)
  takes the child oms:FixedStepMaster (description "oms-ma", its Jacobi master, and stepSize); its
  Python reader (3.0, src/OMSimulatorPython/utils.py) takes SimulationInformation's attributes as a
  solver (name, method "oms_ma", fixedStepSize), which each component names in an annotation of its
  own. libcosim (src/cosim/ssp/ssp_parser.cpp): DefaultExperiment's annotation
  "com.opensimulationplatform", osp:Algorithm/osp:FixedStepAlgorithm baseStepSize. The C++ readers
  match the prefixes (oms:, osp:) as written, so those are the prefixes used. ecos reads no step.
"""
from __future__ import annotations

import io
import time
import zipfile
import xml.etree.ElementTree as ET
from pathlib import Path

from harness.cosim.structure import System
from harness.errors import HarnessError
from harness.fmi.fmu_instance import read_description

SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
BONDS_ANNOTATION = "org.pendulum-harness.bonds"
VIEW_ANNOTATION = "org.pendulum-harness.view"
VIEW_ATTRIBUTES = {"scale": "scale", "frame_rate": "frameRate", "layout": "layout"}  # camera key -> attribute
STEP_ANNOTATION = "org.pendulum-harness.step"
OMS_ANNOTATION = "org.openmodelica"
OMS_NS = "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"
OSP_ANNOTATION = "com.opensimulationplatform"
OSP_NS = "http://opensimulationplatform.com/SSP/OSPAnnotations"
OMS_SOLVER = "master"  # the name by which OMSimulator 3.0 puts each component under the system's solver
FMU_TYPE = "application/x-fmu-sharedlibrary"


def _tag(namespace: str, name: str) -> str:
    return f"{{{namespace}}}{name}"


def _value_element(variable, value, where: str) -> ET.Element:
    """The ssv element holding one start value in the variable's type."""
    kind = variable.type
    if kind in ("Real", "Float64", "Float32"):
        return ET.Element(_tag(SSV_NS, "Real"), value=repr(float(value)))
    if kind == "Enumeration":
        if isinstance(value, str):
            items = {item.name: item.value for item in variable.declaredType.items}
            if value not in items:
                raise HarnessError(f"{where} = {value!r} is not one of {', '.join(items)}")
            value = items[value]
        return ET.Element(_tag(SSV_NS, "Integer"), value=str(int(value)))
    if kind == "Boolean":
        text = str(value).strip().lower()
        return ET.Element(_tag(SSV_NS, "Boolean"), value="true" if text in ("1", "true", "1.0") else "false")
    if kind in ("Integer",) or kind.startswith(("Int", "UInt")):
        return ET.Element(_tag(SSV_NS, "Integer"), value=str(int(float(value))))
    return ET.Element(_tag(SSV_NS, "String"), value=str(value))


def _oms_annotation(annotations: ET.Element, **solver: str) -> ET.Element:
    """An "org.openmodelica" annotation in `annotations`: its oms:SimulationInformation, with `solver`."""
    holder = ET.SubElement(ET.SubElement(annotations, _tag(SSC_NS, "Annotation"), type=OMS_ANNOTATION),
                           _tag(OMS_NS, "Annotations"))
    return ET.SubElement(holder, _tag(OMS_NS, "SimulationInformation"), solver)


def system_structure(system: System, sources: dict[str, str]) -> bytes:
    """The SSD text of `system`, each component's FMU named by `sources` (archive member)."""
    ET.register_namespace("ssd", SSD_NS)
    ET.register_namespace("ssc", SSC_NS)
    ET.register_namespace("ssv", SSV_NS)
    ET.register_namespace("oms", OMS_NS)
    ET.register_namespace("osp", OSP_NS)
    root = ET.Element(_tag(SSD_NS, "SystemStructureDescription"), version="1.0", name=system.name)
    element = ET.SubElement(root, _tag(SSD_NS, "System"), name=system.name)
    elements = ET.SubElement(element, _tag(SSD_NS, "Elements"))
    used: dict[str, dict[str, str]] = {c.name: {} for c in system.components}
    for c in system.connections:
        used[c.source][c.output] = "output"
        used[c.target][c.input] = "input"
    for component in system.components:
        description = read_description(component.fmu)
        variables = {v.name: v for v in description.modelVariables}
        node = ET.SubElement(elements, _tag(SSD_NS, "Component"), name=component.name,
                             source=sources[component.name], type=FMU_TYPE)
        if used[component.name]:  # an empty Connectors element is not allowed
            connectors = ET.SubElement(node, _tag(SSD_NS, "Connectors"))
            for name, kind in sorted(used[component.name].items(), key=lambda item: (item[1], item[0])):
                connector = ET.SubElement(connectors, _tag(SSD_NS, "Connector"), name=name, kind=kind)
                ET.SubElement(connector, _tag(SSC_NS, "Real"))
        if component.start:
            bindings = ET.SubElement(node, _tag(SSD_NS, "ParameterBindings"))
            values = ET.SubElement(ET.SubElement(bindings, _tag(SSD_NS, "ParameterBinding")),
                                   _tag(SSD_NS, "ParameterValues"))
            parameters = ET.SubElement(ET.SubElement(values, _tag(SSV_NS, "ParameterSet"), version="1.0",
                                                     name="initialValues"), _tag(SSV_NS, "Parameters"))
            for name, value in component.start.items():
                where = f"{system.name}: {component.name}.{name}"
                if name not in variables:
                    raise HarnessError(f"{where}: {Path(component.fmu).name} has no such variable")
                parameter = ET.SubElement(parameters, _tag(SSV_NS, "Parameter"), name=name)
                parameter.append(_value_element(variables[name], value, where))
        if system.step is not None:
            _oms_annotation(ET.SubElement(node, _tag(SSD_NS, "Annotations")), name=OMS_SOLVER)
    connections = ET.SubElement(element, _tag(SSD_NS, "Connections")) if system.connections else None
    for c in system.connections:
        ET.SubElement(connections, _tag(SSD_NS, "Connection"), startElement=c.source, startConnector=c.output,
                      endElement=c.target, endConnector=c.input)
    if system.bonds or system.step is not None or system.camera or system.traces or system.description:
        annotations = ET.SubElement(element, _tag(SSD_NS, "Annotations"))  # holds ssc:Annotation elements
        if system.step is not None:
            # first: OMSimulator's C++ reader looks at the system's first annotation only
            information = _oms_annotation(annotations, name=OMS_SOLVER, method="oms_ma",
                                          fixedStepSize=repr(float(system.step)))
            ET.SubElement(information, _tag(OMS_NS, "FixedStepMaster"), description="oms-ma",
                          stepSize=repr(float(system.step)))
            ET.SubElement(annotations, _tag(SSC_NS, "Annotation"), type=STEP_ANNOTATION).append(
                ET.Element("Step", stepSize=repr(float(system.step))))
        if system.bonds:
            annotation = ET.SubElement(ET.SubElement(annotations, _tag(SSC_NS, "Annotation"), type=BONDS_ANNOTATION),
                                       "Bonds")  # an annotation holds one element
            for bond in system.bonds:
                attributes = {"component": bond.component, "force": bond.force, "velocity": bond.velocity}
                if bond.position is not None:
                    attributes["position"] = bond.position
                ET.SubElement(annotation, "Bond", attributes)
        if system.camera or system.traces or system.description:
            view = {attribute: str(system.camera[key]) if key == "layout" else repr(float(system.camera[key]))
                    for key, attribute in VIEW_ATTRIBUTES.items() if key in system.camera}
            if system.description:
                view["description"] = system.description
            holder = ET.SubElement(ET.SubElement(annotations, _tag(SSC_NS, "Annotation"), type=VIEW_ANNOTATION),
                                   "View", view)
            for component, pairs in system.traces.items():
                for x, y in pairs:
                    ET.SubElement(holder, "Trace", component=component, x=x, y=y)
    if system.stop is not None or system.step is not None:
        experiment = ET.SubElement(root, _tag(SSD_NS, "DefaultExperiment"), startTime="0")
        if system.stop is not None:
            experiment.set("stopTime", repr(float(system.stop)))
        if system.step is not None:
            annotation = ET.SubElement(ET.SubElement(experiment, _tag(SSD_NS, "Annotations")),
                                       _tag(SSC_NS, "Annotation"), type=OSP_ANNOTATION)
            ET.SubElement(ET.SubElement(annotation, _tag(OSP_NS, "Algorithm")), _tag(OSP_NS, "FixedStepAlgorithm"),
                          baseStepSize=repr(float(system.step)))
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def write_ssp(system: System, path: Path) -> None:
    """The archive: the SSD and each FMU the system uses once, as resources/<file name> (FMUs of
    one name from different folders get a number)."""
    from harness.output import written
    sources: dict[str, str] = {}
    members: dict[str, Path] = {}
    for component in system.components:
        fmu = Path(component.fmu).resolve()
        member = next((m for m, p in members.items() if p == fmu), None)
        if member is None:
            member = f"resources/{fmu.name}"
            count = 1
            while member in members:
                count += 1
                member = f"resources/{fmu.stem}_{count}{fmu.suffix}"
            members[member] = fmu
        sources[component.name] = member
    ssd = system_structure(system, sources)
    buffer = io.BytesIO()  # the archive is made whole, then replaces the file at once
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        entry = zipfile.ZipInfo("SystemStructure.ssd", date_time=time.localtime()[:6])
        entry.compress_type = zipfile.ZIP_DEFLATED
        entry.external_attr = 0o644 << 16  # readable by all when unpacked, as the FMUs beside it (writestr: 0600)
        archive.writestr(entry, ssd)
        for member, fmu in members.items():
            archive.write(fmu, member)
    with written(path, binary=True) as stream:
        stream.write(buffer.getvalue())
