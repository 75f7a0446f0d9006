"""The harness's own scene file (JSON), read against its schema: every wrong key, type or value is
a one-line HarnessError naming the file and the place.

    {
      "name": "coupled pendulums",
      "description": "free text",
      "stop": 10.0, "step": 0.01,
      "components": {
        "left":   {"fmu": "SimplePendulum", "start": {"phi": 0.5, "solver": "rk4"}, "traces": [["x", "y"]]},
        "spring": {"fmu": "Spring", "start": {"k": 10.0, "l0": 1.5}},
        "right":  {"fmu": "SimplePendulum", "start": {"anchor_x": 1.5}}
      },
      "connections": [["left.x", "spring.a_x"], ["spring.Fa_x", "left.F_x"]],
      "bonds": [["left.F_x", "left.v_x", "left.x"], ["left.F_y", "left.v_y", "left.y"]],
      "accuracy": {"position": 0.001},
      "camera": {"scale": 200, "frame_rate": 25, "layout": "together"}
    }

"fmu" is one of the project's FMU names (built on demand; "fmi3/SimplePendulum" names the FMI 3.0
build) or a path relative to the scene file, of FMI 2.0 or 3.0, mixed as needed. A
start value is a finite number or the name of an enumeration item. Components are stepped in the
order listed (this is the Gauss-Seidel order). "bonds" declares power bonds, each a component's
force input, the velocity output at the same point and, where the force's source also reads the
point's position, that position output (the force's source must read them): the master's
energy-conserving coupling measures the energy each bond creates. "accuracy"
holds "position" (metres) or "pixels" (through the camera's scale). The camera's "layout" is how the
live view (`harness view`) draws the scene: "together" (the default) in one picture, or "side by
side", each group of coupled components in a panel of its own, like the thesis's figures.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from harness.cosim.structure import Bond, Component, Connection, System
from harness.errors import HarnessError
from harness.fmi.fmu_instance import is_number_text
from harness.fmi.fmus import FMU_NAMES, build_dir, build_fmus, locate_fmu, project_fmu_name

MAX_SCENE_BYTES = 16 << 20

# The scene file's format: each object's keys and what they mean. The reader allows exactly these keys, and the
# reference page of the format (docs/reference/scene-file.md) is written from here.
FORMAT = {
    "scene": {
        "name": "the scene's name (text)",
        "description": "free text",
        "stop": "stop time [s], a positive number",
        "step": "communication (macro) step [s], a positive number",
        "components": "object of components by name (keys below); stepped in the order listed, which is the "
                      "Gauss-Seidel order",
        "connections": "list of `[\"source.output\", \"target.input\"]` pairs; an input takes one connection",
        "bonds": "power bonds for the energy-conserving coupling: `[\"c.force_input\", \"c.velocity_output\"]`, "
                 "with the position output third where the force's source reads it",
        "accuracy": "what the planner keeps: `{\"position\": metres}` or `{\"pixels\": n}`",
        "camera": "how the scene is looked at (keys below)",
    },
    "component": {
        "fmu": "a project FMU's name (`SimplePendulum`; `fmi3/SimplePendulum` for FMI 3.0), or a path to an "
               "`.fmu` relative to the scene file",
        "start": "start values and parameters by variable name: a finite number or an enumeration item's name",
        "traces": "pairs of output names to draw, `[[\"x\", \"y\"]]`",
    },
    "accuracy": {
        "position": "tolerance [m] on every traced point at every frame",
        "pixels": "tolerance in pixels, through the camera's scale",
    },
    "camera": {
        "scale": "pixels per metre",
        "frame_rate": "frames per second",
        "layout": "`together` (one picture, the default) or `side by side` (each group of coupled components in a "
                  "panel of its own)",
    },
}
SCENE_KEYS = tuple(FORMAT["scene"])
COMPONENT_KEYS = tuple(FORMAT["component"])
ACCURACY_KEYS = tuple(FORMAT["accuracy"])
CAMERA_KEYS = tuple(FORMAT["camera"])
LAYOUTS = ("together", "side by side")  # the live view: one picture, or one panel per group of coupled components


class _Reader:
    """Checks values at their place in the file; `where` names that place in messages."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, where: str, problem: str) -> HarnessError:
        return HarnessError(f"{self.path}: {where} {problem}")

    def object(self, value, where: str, keys: tuple[str, ...] | None = None) -> dict:
        if not isinstance(value, dict):
            raise self.fail(where, f"must be an object, not {_kind(value)}")
        if keys is not None:
            unknown = [k for k in value if k not in keys]
            if unknown:
                raise self.fail(where, f"has an unknown key {unknown[0]!r} (known: {', '.join(keys)})")
        return value

    def text(self, value, where: str) -> str:
        if not isinstance(value, str):
            raise self.fail(where, f"must be a string, not {_kind(value)}")
        return value

    def positive(self, value, where: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, f"must be a number, not {_kind(value)}")
        if not (math.isfinite(value) and value > 0):
            raise self.fail(where, f"= {value!r} must be a positive finite number")
        return float(value)

    def start_value(self, value, where: str) -> float | str:
        if isinstance(value, str):
            if is_number_text(value):
                raise self.fail(where, f"= {_short(value)} is a string: write a number without quotes")
            return value  # an enumeration item; the FMU's own check names the allowed ones
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, f"must be a number or an enumeration item's name, not {_kind(value)}")
        if not math.isfinite(value):
            raise self.fail(where, f"= {value!r} is not a finite number")
        return value

    def pair(self, value, where: str) -> tuple[str, str]:
        if not (isinstance(value, list) and len(value) == 2 and all(isinstance(v, str) for v in value)):
            raise self.fail(where, f"must be a pair of strings [\"A.output\", \"B.input\"], not {_short(value)}")
        return value[0], value[1]


def _kind(value) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "true/false", type(None): "null",
            int: "a number", float: "a number"}.get(type(value), type(value).__name__)


def _short(value) -> str:
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _no_constants(name: str):
    raise ValueError(f"{name} is not a JSON number")


def _unique_keys(pairs: list[tuple[str, object]]) -> dict:
    result = {}
    for key, value in pairs:
        if key in result:
            raise ValueError(f"the key {key!r} appears twice in one object")
        result[key] = value
    return result


def read_json(path: Path) -> object:
    """A JSON file as Python values: UTF-8, at most MAX_SCENE_BYTES, no NaN or Infinity, no repeated
    keys, nesting no deeper than the parser allows."""
    try:
        with path.open("rb") as stream:
            data = stream.read(MAX_SCENE_BYTES + 1)
    except OSError as error:
        raise HarnessError(f"{path}: cannot read the scene file ({error.strerror})") from None
    if len(data) > MAX_SCENE_BYTES:
        raise HarnessError(f"{path}: larger than {MAX_SCENE_BYTES} bytes, too large for a scene file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise HarnessError(f"{path}: not UTF-8 text (byte {error.start})") from None
    try:
        return _plain_text(json.loads(text, parse_constant=_no_constants, parse_int=_whole_number,
                                      object_pairs_hook=_unique_keys), path)
    except json.JSONDecodeError as error:
        raise HarnessError(f"{path}: not valid JSON (line {error.lineno}, column {error.colno}: {error.msg})") from None
    except ValueError as error:
        raise HarnessError(f"{path}: {error}") from None
    except RecursionError:
        raise HarnessError(f"{path}: nested too deeply to be a scene file") from None


def trace_problem(fmu: Path, pairs: list[tuple[str, str]]) -> str | None:
    """Why these column pairs cannot be traces of the FMU's component, or None."""
    from harness.fmi.fmu_instance import read_description
    outputs = [v.name for v in read_description(fmu).modelVariables if v.causality == "output"]
    for name in (name for pair in pairs for name in pair):
        if name not in outputs:
            return f"names {name!r}, which is not an output of {fmu.name} (outputs: {', '.join(outputs)})"
    return None


def _plain_text(document, path: Path):
    """Every string (keys too) can name a file and be printed: no NUL, no unpaired surrogate (JSON's
    \\u escapes allow both)."""
    pending = [document]
    while pending:
        value = pending.pop()
        if isinstance(value, dict):
            pending.extend(value.keys())
            pending.extend(value.values())
        elif isinstance(value, list):
            pending.extend(value)
        elif isinstance(value, str) and ("\0" in value or any("\ud800" <= c <= "\udfff" for c in value)):
            raise HarnessError(f"{path}: the string {value.encode('utf-8', 'backslashreplace').decode()[:60]!r} "
                               "holds a NUL or an unpaired surrogate, which no file name or text can")
    return document


def _whole_number(digits: str) -> int | float:
    """A JSON integer; one too long for a float becomes infinity, which the schema refuses by name."""
    return int(digits) if len(digits) <= 300 else float(digits)


def _split(reference: str, where: str, read: _Reader) -> tuple[str, str]:
    component, sep, variable = reference.partition(".")
    if not sep or not component or not variable:
        raise read.fail(where, f"{reference!r} must be COMPONENT.VARIABLE")
    return component, variable


def _fmu_path(value: str, base: Path, where: str, read: _Reader) -> Path:
    if project_fmu_name(value):
        return locate_fmu(value)
    path = (base / value).resolve()
    if not path.is_file():
        raise read.fail(where, f"{value!r}: no such FMU (looked for {path}; project FMUs: {', '.join(FMU_NAMES)})")
    return path


def _project_fmus(specs: dict) -> list[str]:
    """The project FMUs the components name (the rest is checked as each component is read)."""
    return [spec["fmu"] for spec in specs.values()
            if isinstance(spec, dict) and isinstance(spec.get("fmu"), str) and project_fmu_name(spec["fmu"])]


def scene_project_fmus(path: str | Path) -> list[str]:
    """The project FMUs a scene file (.json) names; none for anything else or a file that does not read
    (loading it says why)."""
    try:
        data = read_json(Path(path)) if Path(path).suffix == ".json" else None
    except HarnessError:
        return []
    specs = data.get("components") if isinstance(data, dict) else None
    return _project_fmus(specs) if isinstance(specs, dict) else []


def load_scene_file(path: Path) -> System:
    read = _Reader(path)
    data = read.object(read_json(path), "the scene", SCENE_KEYS)
    name = read.text(data.get("name", path.stem), "\"name\"")
    description = read.text(data["description"], "\"description\"") if "description" in data else ""
    stop = read.positive(data["stop"], "\"stop\"") if "stop" in data else None
    step = read.positive(data["step"], "\"step\"") if "step" in data else None
    if "components" not in data:
        raise read.fail("the scene", "needs a \"components\" object")
    specs = read.object(data["components"], "\"components\"")
    if not specs:
        raise read.fail("\"components\"", "is empty")
    missing = [name for name in _project_fmus(specs) if not (build_dir() / "fmus" / f"{name}.fmu").is_file()]
    if missing:  # built in one go, not one at a time as each is located
        build_fmus(missing)
    components, traces = [], {}
    for component_name, spec in specs.items():
        where = f"component {component_name!r}"
        spec = read.object(spec, where, COMPONENT_KEYS)
        if "fmu" not in spec:
            raise read.fail(where, "needs an \"fmu\"")
        fmu = _fmu_path(read.text(spec["fmu"], f"{where}: \"fmu\""), path.parent, f"{where}: \"fmu\"", read)
        start = {variable: read.start_value(value, f"{where}: start value {variable!r}")
                 for variable, value in read.object(spec.get("start", {}), f"{where}: \"start\"").items()}
        components.append(Component(component_name, fmu, start))
        if "traces" in spec:
            if not isinstance(spec["traces"], list):
                raise read.fail(f"{where}: \"traces\"", f"must be a list of column pairs, not {_kind(spec['traces'])}")
            if not spec["traces"]:
                raise read.fail(f"{where}: \"traces\"", "is empty: list at least one pair of columns, or leave it out")
            traces[component_name] = [read.pair(p, f"{where}: a trace") for p in spec["traces"]]
            problem = trace_problem(fmu, traces[component_name])
            if problem:
                raise read.fail(f"{where}: a trace", problem)
    connections = []
    pairs = data.get("connections", [])
    if not isinstance(pairs, list):
        raise read.fail("\"connections\"", f"must be a list of pairs, not {_kind(pairs)}")
    for pair in pairs:
        output, input_ = read.pair(pair, "a connection")
        (source, out_name), (target, in_name) = (_split(output, "a connection", read),
                                                 _split(input_, "a connection", read))
        connections.append(Connection(source, out_name, target, in_name))
    bonds = []
    listed = data.get("bonds", [])
    if not isinstance(listed, list):
        raise read.fail("\"bonds\"", f"must be a list of [force, velocity] or [force, velocity, position] lists, "
                                     f"not {_kind(listed)}")
    for entry in listed:
        if not isinstance(entry, list) or len(entry) not in (2, 3) or not all(isinstance(x, str) for x in entry):
            raise read.fail("a bond", f"{entry!r} must be a list of two or three \"component.variable\" texts: "
                                      "force input, velocity output and optionally position output")
        parts = [_split(x, "a bond", read) for x in entry]
        if len({component for component, _ in parts}) != 1:
            raise read.fail("a bond", f"{', '.join(entry)}: the force input and the velocity (and position) output "
                                      "belong to one component")
        bonds.append(Bond(parts[0][0], *(name for _, name in parts)))
    accuracy = read.object(data.get("accuracy", {}), "\"accuracy\"", ACCURACY_KEYS)
    if len(accuracy) > 1:
        raise read.fail("\"accuracy\"", "takes \"position\" or \"pixels\", not both")
    camera = read.object(data.get("camera", {}), "\"camera\"", CAMERA_KEYS)
    accuracy = {k: read.positive(v, f"\"accuracy\": {k!r}") for k, v in accuracy.items()}
    layout = camera.pop("layout", None)
    if layout is not None and layout not in LAYOUTS:
        raise read.fail("\"camera\": 'layout'", f"{_short(layout)} must be one of {', '.join(map(repr, LAYOUTS))}")
    camera = {k: read.positive(v, f"\"camera\": {k!r}") for k, v in camera.items()}
    if layout is not None:
        camera["layout"] = layout
    return System(name, components, connections, stop, step, accuracy, camera, traces, origin=str(path),
                  bonds=bonds, description=description)
