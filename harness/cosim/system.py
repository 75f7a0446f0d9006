"""A coupled system: components (FMUs with start values) and connections between their variables.

Read from the harness's own scene file (JSON) or from SSP 1.0 (an `.ssp` archive, a folder holding
`SystemStructure.ssd`, or an `.ssd` file next to its resources) through fmpy's SSD reader; parameter
bindings of the SSD (inline or `.ssv` files) become start values.

Scene file:

    {
      "name": "coupled pendulums",
      "stop": 10.0, "step": 0.01,
      "components": {
        "left":   {"fmu": "SimplePendulum", "start": {"phi": 0.5}},
        "spring": {"fmu": "Spring", "start": {"k": 10.0, "l0": 1.5}},
        "right":  {"fmu": "SimplePendulum", "start": {"anchor_x": 1.5}}
      },
      "connections": [["left.x", "spring.a_x"], ["spring.Fa_x", "left.F_x"]]
    }

"fmu" is one of the project's FMU names (built on demand) or a path relative to the scene file.
Components are stepped in the order listed (this is the Gauss-Seidel order).
"""
from __future__ import annotations

import io
import json
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

from harness.errors import HarnessError
from harness.fmi.fmus import FMU_NAMES, locate_fmu


@dataclass
class Component:
    name: str
    fmu: Path
    start: dict[str, float | int | str] = field(default_factory=dict)


@dataclass(frozen=True)
class Connection:
    source: str  # component name
    output: str  # variable name
    target: str
    input: str

    def __str__(self) -> str:
        return f"{self.source}.{self.output} -> {self.target}.{self.input}"


@dataclass
class System:
    name: str
    components: list[Component]
    connections: list[Connection]
    stop: float | None = None
    step: float | None = None
    # a scene's visual needs (scene files only): {"position": metres} or {"pixels": n}, and the camera
    accuracy: dict = field(default_factory=dict)
    camera: dict = field(default_factory=dict)  # {"scale": pixels per metre, "frame_rate": frames per second}
    traces: dict = field(default_factory=dict)  # component -> [[x column, y column], ...] to draw

    def tolerance(self) -> float | None:
        """The position tolerance in metres the scene asks for (pixels through the camera's scale)."""
        if "position" in self.accuracy:
            return float(self.accuracy["position"])
        if "pixels" in self.accuracy:
            scale = self.camera.get("scale")
            if not scale or scale <= 0:
                raise HarnessError(f"{self.name}: an accuracy in pixels needs the camera's \"scale\" (pixels per metre)")
            return float(self.accuracy["pixels"]) / float(scale)
        return None

    def frame_step(self) -> float | None:
        """The interval at which the scene is looked at: 1 / frame rate, else the communication step."""
        rate = self.camera.get("frame_rate")
        return 1.0 / float(rate) if rate else self.step

    def component(self, name: str) -> Component:
        for c in self.components:
            if c.name == name:
                return c
        raise HarnessError(f"system {self.name!r} has no component {name!r}")


def _split(reference: str, where: str) -> tuple[str, str]:
    component, sep, variable = reference.partition(".")
    if not sep or not component or not variable:
        raise HarnessError(f"{where}: {reference!r} must be COMPONENT.VARIABLE")
    return component, variable


def _fmu_path(value: str, base: Path) -> Path:
    if value in FMU_NAMES:
        return locate_fmu(value)
    path = (base / value).resolve()
    if not path.is_file():
        raise HarnessError(f"FMU {value!r} not found (looked for {path})")
    return path


def load_scene_file(path: Path) -> System:
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise HarnessError(f"{path}: cannot read the scene file ({error})") from None
    if not isinstance(data, dict) or not isinstance(data.get("components"), dict):
        raise HarnessError(f"{path}: a scene file needs a \"components\" object")
    components, traces = [], {}
    for name, spec in data["components"].items():
        if not isinstance(spec, dict) or "fmu" not in spec:
            raise HarnessError(f"{path}: component {name!r} needs an \"fmu\"")
        components.append(Component(name, _fmu_path(spec["fmu"], path.parent), dict(spec.get("start", {}))))
        if "traces" in spec:
            traces[name] = [tuple(pair) for pair in spec["traces"]]
    connections = []
    for pair in data.get("connections", []):
        if not (isinstance(pair, list) and len(pair) == 2):
            raise HarnessError(f"{path}: a connection is a pair [\"A.output\", \"B.input\"], got {pair!r}")
        (source, output), (target, input_) = _split(pair[0], str(path)), _split(pair[1], str(path))
        connections.append(Connection(source, output, target, input_))
    for key in ("accuracy", "camera"):
        if not isinstance(data.get(key, {}), dict):
            raise HarnessError(f"{path}: \"{key}\" must be an object")
    return System(data.get("name", path.stem), components, connections, data.get("stop"), data.get("step"),
                  dict(data.get("accuracy", {})), dict(data.get("camera", {})), traces)


def _ssp_archive(path: Path) -> tuple[io.BytesIO | Path, Path]:
    """(what fmpy's read_ssd can open, folder the component sources are relative to)."""
    if path.is_file() and path.suffix == ".ssp":
        root = Path(tempfile.mkdtemp(prefix="ssp_"))
        try:
            with zipfile.ZipFile(path) as archive:
                archive.extractall(root)
        except zipfile.BadZipFile:
            raise HarnessError(f"{path}: not a valid .ssp (zip) archive") from None
        return path, root
    if path.is_dir():
        root, ssd = path, path / "SystemStructure.ssd"
    elif path.is_file() and path.suffix == ".ssd":
        root, ssd = path.parent, path
    else:
        raise HarnessError(f"{path}: expected a scene file (.json), an .ssp archive, an .ssd file or a folder with "
                           "SystemStructure.ssd")
    if not ssd.is_file():
        raise HarnessError(f"{path}: no SystemStructure.ssd in this folder")
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.write(ssd, "SystemStructure.ssd")
        for extra in root.rglob("*.ss[vm]"):  # parameter values and mappings referenced by the SSD
            archive.write(extra, extra.relative_to(root).as_posix())
    buffer.seek(0)
    return buffer, root


def _bound_values(element) -> dict[str, str]:
    values = {}
    for binding in getattr(element, "parameterBindings", []):
        prefix = binding.prefix or ""
        for parameter_set in binding.parameterValues:
            for parameter in parameter_set.parameters:
                name = parameter.name[len(prefix):] if prefix and parameter.name.startswith(prefix) else parameter.name
                values[name] = float(parameter.value) if parameter.type == "Real" else (
                    int(parameter.value) if parameter.type in ("Integer", "Enumeration") else parameter.value)
    return values


def _default_stop_time(archive) -> float | None:
    """stopTime of the SSD's DefaultExperiment (fmpy's reader does not keep it)."""
    import xml.etree.ElementTree as ET
    if hasattr(archive, "seek"):
        archive.seek(0)
    with zipfile.ZipFile(archive) as zipped:
        root = ET.fromstring(zipped.read("SystemStructure.ssd"))
    if hasattr(archive, "seek"):
        archive.seek(0)
    for element in root:
        if element.tag.endswith("}DefaultExperiment") and element.get("stopTime") is not None:
            return float(element.get("stopTime"))
    return None


def load_ssp(path: Path) -> System:
    from fmpy.ssp.ssd import Component as SspComponent, read_ssd
    archive, root = _ssp_archive(path)
    try:
        ssd = read_ssd(archive)
    except Exception as error:  # lxml and schema errors come as several types
        raise HarnessError(f"{path}: malformed SSD ({str(error).splitlines()[0] if str(error) else error})") from None
    system = ssd.system
    components = []
    system_values = _bound_values(system)
    for element in system.elements:
        if not isinstance(element, SspComponent):
            continue
        fmu = root / element.source
        if not fmu.is_file():
            raise HarnessError(f"{path}: component {element.name!r}: source {element.source} not found")
        start = {k.split(".", 1)[1]: v for k, v in system_values.items() if k.startswith(element.name + ".")}
        start.update(_bound_values(element))
        components.append(Component(element.name, fmu, start))
    connections = [Connection(c.startElement, c.startConnector, c.endElement, c.endConnector)
                   for c in system.connections]
    stop = _default_stop_time(archive)
    step = None
    info = getattr(system, "simulationInformation", None)
    if info is not None and getattr(info, "fixedStepMaster", None) is not None:
        step = float(info.fixedStepMaster.stepSize)
    return System(ssd.name or path.stem, components, connections, stop, step)


def load_system(path: str | Path) -> System:
    path = Path(path)
    if not path.exists():
        raise HarnessError(f"{path}: no such file or folder")
    if path.suffix == ".json":
        return load_scene_file(path)
    return load_ssp(path)
