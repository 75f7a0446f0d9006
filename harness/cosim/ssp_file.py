"""SSP 1.0 systems through fmpy's SSD reader: an `.ssp` archive, a folder holding
`SystemStructure.ssd`, or an `.ssd` file next to its resources. Parameter bindings (inline or
`.ssv` files) become start values.

From an archive only what the system uses is taken out: the SSD and its parameter files are read
in memory, and each component's FMU, which must be a member of the archive, is extracted (bounded,
see harness/archives.py) into a temporary folder that the returned System owns.
"""
from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path, PurePosixPath

from harness.archives import (MAX_BYTES, MAX_READ, extract_members, name_problem, open_archive, read_member,
                              remove_folder, temporary_folder)
from harness.cosim.structure import Bond, Component, Connection, System
from harness.errors import HarnessError, first_problem
from harness.fmi.fmu_instance import read_description

SSD = "SystemStructure.ssd"


def _in_memory_ssd(files: dict[str, bytes]) -> io.BytesIO:
    """A zip holding the SSD and its parameter files: what fmpy's read_ssd opens."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    buffer.seek(0)
    return buffer


def _referenced(ssd_bytes: bytes, what: str) -> list[str]:
    """The parameter files (.ssv, .ssm) that the SSD's bindings name: the only ones read."""
    try:
        root = ET.fromstring(ssd_bytes)
    except ET.ParseError as error:
        raise HarnessError(f"{what}: malformed SSD ({error})") from None
    names = [element.get("source") for element in root.iter()
             if element.tag.endswith(("}ParameterBinding", "}ParameterMapping")) and element.get("source")]
    return list(dict.fromkeys(names))


def _checked_total(files: dict[str, bytes], what: str) -> dict[str, bytes]:
    if sum(map(len, files.values())) > MAX_BYTES:
        raise HarnessError(f"{what}: the SSD and its parameter files hold more than {MAX_BYTES} bytes (the bound)")
    return files


def _ssd_files_from_archive(archive: zipfile.ZipFile, what: str) -> dict[str, bytes]:
    if SSD not in archive.namelist():
        raise HarnessError(f"{what}: no {SSD} in the archive")
    files = {SSD: read_member(archive, SSD, what)}
    for name in _referenced(files[SSD], what):
        if name not in archive.namelist():
            raise HarnessError(f"{what}: parameter file {name!r} named by the SSD is not in the archive")
        files[name] = read_member(archive, name, what)
        _checked_total(files, what)
    return files


def _ssd_files_from_folder(root: Path, ssd: Path) -> dict[str, bytes]:
    def read(path: Path, what: str) -> bytes:
        if not path.is_file():  # a pipe or device would block or never end
            raise HarnessError(f"{what}: not found or not a regular file")
        try:
            with path.open("rb") as stream:
                data = stream.read(MAX_READ + 1)
        except OSError as error:
            raise HarnessError(f"{what}: cannot read ({error.strerror})") from None
        if len(data) > MAX_READ:
            raise HarnessError(f"{what}: more than {MAX_READ} bytes, too large")
        return data
    files = {SSD: read(ssd, str(ssd))}
    for name in _referenced(files[SSD], str(ssd)):
        files[name] = read(root / name, f"{ssd}: parameter file {name!r}")
        _checked_total(files, str(ssd))
    return files


def _number(text: str | None, what: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise HarnessError(f"{what} = {text!r} is not a number") from None
    if not math.isfinite(value):
        raise HarnessError(f"{what} = {text!r} is not a finite number")
    return value


def _is_number(text) -> bool:
    try:
        float(text)
    except (TypeError, ValueError):
        return False
    return True


def _units_match(fmu: Path, units: dict[str, str], what: str) -> None:
    """A value given in a unit other than its variable's would need a conversion this harness does
    not make: refused by name."""
    if not units:
        return
    declared = {v.name: v.unit or (v.declaredType.unit if v.declaredType is not None else None)
                for v in read_description(fmu).modelVariables}
    for name, unit in units.items():
        if name in declared and declared[name] != unit:
            raise HarnessError(f"{what}: parameter {name!r} is given in {unit!r}, but the FMU's variable is in "
                               f"{declared[name]!r}; unit conversion is not supported")


def _bound_values(element, what: str, units: dict[str, str] | None = None) -> dict[str, float | int | str]:
    """The parameter values bound to an element; the units they are given in go into `units`."""
    values: dict[str, float | int | str] = {}
    for binding in getattr(element, "parameterBindings", []):
        prefix = binding.prefix or ""
        for parameter_set in binding.parameterValues:
            for parameter in parameter_set.parameters:
                if not parameter.name:
                    raise HarnessError(f"{what}: a parameter without a name")
                name = parameter.name[len(prefix):] if prefix and parameter.name.startswith(prefix) else parameter.name
                where = f"{what}: parameter {name!r}"
                if getattr(parameter, "unit", None) and units is not None:
                    units[name] = parameter.unit
                if parameter.type == "Enumeration" and not _is_number(parameter.value):
                    values[name] = str(parameter.value)  # SSP names the item; the FMU's items decide
                elif parameter.type == "Real":
                    values[name] = _number(parameter.value, where)
                elif parameter.type in ("Integer", "Enumeration"):
                    number = _number(parameter.value, where)
                    if number != int(number):
                        raise HarnessError(f"{where} = {parameter.value!r} is not an integer")
                    values[name] = int(number)
                else:
                    values[name] = parameter.value
    return values


TRANSFORMATIONS = ("LinearTransformation", "BooleanMappingTransformation", "IntegerMappingTransformation",
                   "EnumerationMappingTransformation")


def _refuse_transformations(root: ET.Element, what: str) -> None:
    """Connections that transform what they carry (read from the XML: fmpy's reader misses them in
    the namespace SSP 1.0 puts them in)."""
    for connection in root.iter():
        if not connection.tag.endswith("}Connection"):
            continue
        for child in connection:
            kind = child.tag.rpartition("}")[2]
            if kind in TRANSFORMATIONS:
                raise HarnessError(f"{what}: connection "
                                   f"{connection.get('startElement')}.{connection.get('startConnector')}"
                                   f" -> {connection.get('endElement')}.{connection.get('endConnector')} has a {kind}, "
                                   "which is not supported")


def _bonds(root: ET.Element, what: str) -> list[Bond]:
    """Power bonds from the system's annotation (`harness.cosim.ssp_export`); none without it."""
    from harness.cosim.ssp_export import BONDS_ANNOTATION
    bonds = []
    for annotation in root.iter():
        if not (annotation.tag.endswith("}Annotation") and annotation.get("type") == BONDS_ANNOTATION):
            continue
        for bond in (entry for holder in annotation for entry in holder):
            names = [bond.get(key) for key in ("component", "force", "velocity")]
            if bond.tag != "Bond" or not all(names):
                raise HarnessError(f"{what}: annotation {BONDS_ANNOTATION}: each entry is a Bond with component, "
                                   "force and velocity (and optionally position)")
            bonds.append(Bond(*names, bond.get("position")))
    return bonds


def _annotated_step(root: ET.Element, what: str) -> float | None:
    """The communication step an annotation gives: this harness's own, which decides, else libcosim's,
    else OMSimulator's (either reader's form, see harness.cosim.ssp_export), so that an SSP made for
    those runs at its step here too."""
    from harness.cosim.ssp_export import OMS_ANNOTATION, OSP_ANNOTATION, STEP_ANNOTATION
    forms = ((STEP_ANNOTATION, "Step", "stepSize"), (OSP_ANNOTATION, "FixedStepAlgorithm", "baseStepSize"),
             (OMS_ANNOTATION, "FixedStepMaster", "stepSize"),
             (OMS_ANNOTATION, "SimulationInformation", "fixedStepSize"))
    for kind, name, attribute in forms:
        for annotation in root.iter():
            if not (annotation.tag.endswith("}Annotation") and annotation.get("type") == kind):
                continue
            for element in annotation.iter():
                # the harness's own must hold its step; the others' elements may serve other ends
                if element.tag.rpartition("}")[2] == name and (kind == STEP_ANNOTATION or element.get(attribute)):
                    return _number(element.get(attribute), f"{what}: annotation {kind} {name} {attribute}")
    return None


def _view(root: ET.Element, what: str, components: list[Component]) -> tuple[dict, dict, str]:
    """The camera, traces and description a system exported by this harness carries in an annotation."""
    from harness.cosim.scene_file import LAYOUTS, trace_problem
    from harness.cosim.ssp_export import VIEW_ANNOTATION, VIEW_ATTRIBUTES
    camera, traces, description = {}, {}, ""
    fmus = {c.name: c.fmu for c in components}
    for annotation in root.iter():
        if not (annotation.tag.endswith("}Annotation") and annotation.get("type") == VIEW_ANNOTATION):
            continue
        for view in annotation:
            where = f"{what}: annotation {VIEW_ANNOTATION}"
            for key, attribute in VIEW_ATTRIBUTES.items():
                value = view.get(attribute)
                if value is None:
                    continue
                if key == "layout":
                    if value not in LAYOUTS:
                        raise HarnessError(f"{where}: layout {value!r} must be one of {', '.join(map(repr, LAYOUTS))}")
                    camera[key] = value
                else:
                    camera[key] = _number(value, f"{where} {attribute}")
                    if not camera[key] > 0:
                        raise HarnessError(f"{where}: {attribute} = {value} must be a positive number")
            description = view.get("description", "")
            for trace in view:
                component, pair = trace.get("component"), (trace.get("x"), trace.get("y"))
                if trace.tag != "Trace" or component not in fmus or not all(pair):
                    raise HarnessError(f"{where}: each entry is a Trace with x and y of a component of the system")
                problem = trace_problem(fmus[component], [pair])
                if problem:
                    raise HarnessError(f"{where}: the trace of {component!r} {problem}")
                traces.setdefault(component, []).append(pair)
    return camera, traces, description


def _experiment(root: ET.Element, what: str) -> float | None:
    """stopTime of the SSD's DefaultExperiment (fmpy's reader does not keep it)."""
    for element in root:
        if not element.tag.endswith("}DefaultExperiment"):
            continue
        if element.get("startTime") is not None and _number(element.get("startTime"),
                                                            f"{what}: DefaultExperiment startTime") != 0.0:
            raise HarnessError(f"{what}: DefaultExperiment startTime = {element.get('startTime')}: runs start at "
                               "t = 0 (another start time is not supported)")
        if element.get("stopTime") is not None:
            return _number(element.get("stopTime"), f"{what}: DefaultExperiment stopTime")
    return None


FMU_TYPE = "application/x-fmu-sharedlibrary"


def _refuse_unsupported(system, what: str) -> None:
    """SSP features this harness does not carry out: refused rather than silently ignored."""
    from fmpy.ssp.ssd import Component as SspComponent
    for element in system.elements:
        if not isinstance(element, SspComponent):
            raise HarnessError(f"{what}: element {getattr(element, 'name', '')!r} is a {type(element).__name__}; "
                               "only FMU components are supported (no nested systems or signal dictionaries)")
        if element.type not in (None, FMU_TYPE):
            raise HarnessError(f"{what}: component {element.name!r} has type {element.type!r}; only {FMU_TYPE} "
                               "is supported")
    if getattr(system, "signalDictionaries", None):
        raise HarnessError(f"{what}: signal dictionaries are not supported")
    for connection in system.connections:
        if connection.startElement is None or connection.endElement is None:
            raise HarnessError(f"{what}: connection {connection.startConnector} -> {connection.endConnector} "
                               "joins a connector of the system itself; only components may be connected")
    for holder in (system, *system.elements):
        for binding in getattr(holder, "parameterBindings", []):
            if binding.parameterMapping:
                raise HarnessError(f"{what}: {getattr(holder, 'name', None) or 'the system'} has a "
                                   "ParameterMapping, which is not supported")


def load_ssp(path: Path) -> System:
    from fmpy.ssp.ssd import read_ssd
    what = str(path)
    is_archive = path.is_file() and path.suffix == ".ssp"
    if is_archive:
        with open_archive(path, what) as archive:
            files = _ssd_files_from_archive(archive, what)
        root = None
    else:
        if path.is_dir():
            root, ssd_path = path, path / SSD
        elif path.is_file() and path.suffix == ".ssd":
            root, ssd_path = path.parent, path
        else:
            raise HarnessError(f"{path}: expected a scene file (.json), an .ssp archive, an .ssd file or a folder "
                               f"with {SSD}")
        if not ssd_path.is_file():
            raise HarnessError(f"{path}: no {SSD} in this folder")
        files = _ssd_files_from_folder(root, ssd_path)
    try:
        ssd = read_ssd(_in_memory_ssd(files))
        ssd_root = ET.fromstring(files[SSD])
        stop = _experiment(ssd_root, what)
        bonds = _bonds(ssd_root, what)
        _refuse_transformations(ssd_root, what)
        for component in ssd_root.iter():  # read from the XML: fmpy's reader does not keep it
            if component.tag.endswith("}Component") and component.get("implementation") not in (None, "any",
                                                                                                   "CoSimulation"):
                raise HarnessError(f"{what}: component {component.get('name')!r} asks for implementation "
                                   f"{component.get('implementation')!r}; the master runs every FMU as Co-Simulation")
    except HarnessError:
        raise
    except Exception as error:  # lxml, schema and reader errors come as several types
        raise HarnessError(f"{path}: malformed SSD ({first_problem(error)})") from None
    system = ssd.system
    _refuse_unsupported(system, what)
    system_units: dict[str, str] = {}
    system_values = _bound_values(system, what, system_units)
    elements = system.elements
    for name in system_values:
        if name.split(".", 1)[0] not in {e.name for e in elements} or "." not in name:
            raise HarnessError(f"{what}: system parameter {name!r} names no component's variable "
                               "(expected COMPONENT.VARIABLE)")
    sources = {}
    for element in elements:
        source = element.source or ""
        if is_archive:
            problem = name_problem(source)
            if problem or not source:
                raise HarnessError(f"{path}: component {element.name!r}: source {source!r} "
                                   f"{problem or 'is empty'}; an .ssp loads its FMUs from inside the archive")
            source = PurePosixPath(source).as_posix()
        sources[element.name] = source
    workspace = temporary_folder("ssp_") if is_archive and elements else None
    try:
        if workspace is not None:
            with open_archive(path, what) as archive:
                missing = sorted(s for s in sources.values() if s not in archive.namelist())
                if missing:
                    raise HarnessError(f"{path}: source {missing[0]} not found in the archive")
                extract_members(archive, workspace, set(sources.values()).__contains__, what)
        base = workspace if workspace is not None else root
        components = []
        for element in elements:
            fmu = base / sources[element.name]
            if not fmu.is_file():
                raise HarnessError(f"{path}: component {element.name!r}: source {sources[element.name]} not found")
            start = {k.split(".", 1)[1]: v for k, v in system_values.items() if k.startswith(element.name + ".")}
            units = {k.split(".", 1)[1]: v for k, v in system_units.items() if k.startswith(element.name + ".")}
            start.update(_bound_values(element, f"{what}: component {element.name!r}", units))
            _units_match(fmu, units, f"{what}: component {element.name!r}")
            components.append(Component(element.name, fmu, start))
        connections = [Connection(c.startElement, c.startConnector, c.endElement, c.endConnector)
                       for c in system.connections]
        step = _annotated_step(ssd_root, what)
        info = getattr(system, "simulationInformation", None)
        if info is not None and getattr(info, "fixedStepMaster", None) is not None:
            step = _number(info.fixedStepMaster.stepSize, f"{what}: FixedStepMaster stepSize")
        camera, traces, description = _view(ssd_root, what, components)
        return System(ssd.name or path.stem, components, connections, stop, step, camera=camera, traces=traces,
                      workspace=workspace, origin=what, bonds=bonds, description=description)
    except BaseException:
        if workspace is not None:
            remove_folder(workspace)
        raise
