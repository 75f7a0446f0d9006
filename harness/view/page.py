"""`harness view SCENE --out DIR`: the scene live in a browser, as one self-contained page.

DIR/index.html holds everything it needs, nothing from the network: the WebAssembly module of
each FMU the scene names (built from the sources the FMU carries, harness.view.wasm), what the
page knows of each FMU (value references, outputs, methods, and from the object file it carries
the points to draw and the coordinates a drag sets), the scene, and the JavaScript of web/ (the
FMI importer, the master, the drag, the exact pendulum, the page), joined into one script. It
works opened as a file and served by `python -m http.server`. Loaded as index.html?check=T it runs
the scene for T seconds without drawing and writes the final state into <pre id="check">.
"""
from __future__ import annotations

import base64
import html
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import sympy as sp

from harness.cosim import contact_guard
from harness.cosim.master import MasterOptions, run_system
from harness.cosim.system import System, component_files, load_system
from harness.errors import HarnessError, where
from harness.fmi.fmu_instance import FmuInstance, read_description
from harness.fmi.methods import ORDER_SETTING
from harness.fmi.simulation import MAX_POINTS
from harness.objects.object_file import ObjectSpec
from harness.objects.proof import object_file_in
from harness.output import output_file, output_folder, written
from harness.view.wasm import WEB, build_modules

# The page's script: web/ modules in dependency order, joined (their relative imports dropped).
SCRIPTS = ("fmu.mjs", "exact.mjs", "master.mjs", "pose.mjs", "view.mjs")
TEMPLATE = "view.html"
# The objects whose motion is known exactly (web/exact.mjs): the page shows their error live.
EXACT = {"SimplePendulum": "simple pendulum"}
MAX_FRAME_RATE = 60.0
MAX_STEPS_PER_FRAME = 10_000


@dataclass
class ViewPage:
    path: Path                   # DIR/index.html
    bytes: int                   # its size
    modules: dict[str, int]      # model identifier -> size of its WebAssembly module [bytes]


def write_view(scene: str | Path, out: str | Path, step: float | None = None) -> ViewPage:
    """Writes DIR/index.html for the scene (a scene file or an SSP), stepped at its communication step
    or at `step`; see the module's note."""
    if str(out) == "":
        raise HarnessError("--out '': names no folder")
    if Path(out).exists() and not Path(out).is_dir():
        raise HarnessError(f"--out {out}: is a file, not a folder")
    with load_system(scene) as system:
        if step is not None:
            if not (step > 0 and math.isfinite(step)):
                raise HarnessError(f"--step {step}: must be a positive number")
            system.step = step
        if system.step is None:
            raise HarnessError(f"{scene}: the live view steps the scene at its communication step: give \"step\" in "
                               "the scene, or --step")
        frame_rate = _frame_rate(system)
        # refused before anything is built: an output that would replace an input
        index = output_file(Path(out) / "index.html", "--out", component_files(scene, system))
        # the scene as the harness's master runs it: connections, start values, a first step
        run_system(system, MasterOptions(stop=system.step, step=system.step))
        fmus = list(dict.fromkeys(c.fmu for c in system.components))
        modules = build_modules(fmus)
        keys = _module_keys(fmus)
        specs = {f: object_file_in(f) for f in fmus}  # each object file read once, for its module and its shapes
        payload = _payload(system, {keys[f]: _module(f, modules[f], specs[f]) for f in fmus}, keys, specs, frame_rate)
    text = _page(payload)
    output_folder(out, "--out")  # made only now: a refused scene leaves no folder
    with written(index) as sink:
        sink.write(text)
    return ViewPage(index, len(text.encode()), {payload["modules"][keys[f]]["identifier"]: len(modules[f])
                                                for f in fmus})


def _frame_rate(system: System) -> float:
    """The frames per second the page draws: the camera's, else one per step, between 10 and 60 (a
    display shows no more). A frame may take at most MAX_STEPS_PER_FRAME macro steps, and a step may
    wait at most a minute of frames."""
    rate = min(float(system.camera.get("frame_rate", max(10.0, 1.0 / system.step))), MAX_FRAME_RATE)
    steps = 1.0 / (rate * system.step)
    if steps > MAX_STEPS_PER_FRAME:
        raise HarnessError(f"{system.name}: at {rate:g} frames per second a step of {system.step:g} s makes "
                           f"{steps:.3g} macro steps per frame, more than the live view's {MAX_STEPS_PER_FRAME}: "
                           "choose a larger step (--step) or a higher frame rate")
    if steps * 60 * rate < 1:
        raise HarnessError(f"{system.name}: a step of {system.step:g} s would show the scene move less than once a "
                           "minute: choose a smaller step (--step) or a lower frame rate")
    return rate


def _module_keys(fmus: list[Path]) -> dict[Path, str]:
    """A name per FMU file: its model identifier, numbered where two files share one."""
    keys: dict[Path, str] = {}
    for fmu in fmus:
        identifier = read_description(fmu).coSimulation.modelIdentifier
        key, n = identifier, 1
        while key in keys.values():
            n += 1
            key = f"{identifier}_{n}"
        keys[fmu] = key
    return keys


def _kind(variable) -> str:
    return {"Real": "real", "Integer": "integer", "Enumeration": "integer", "Boolean": "boolean"}.get(variable.type, "")


def _module(fmu: Path, wasm: bytes, spec: ObjectSpec | None) -> dict:
    """What the page knows of one FMU."""
    md = read_description(fmu)
    variables = md.modelVariables
    by_name = {v.name: v for v in variables}
    outputs = [v for v in variables if v.causality == "output"]
    solver = by_name.get("solver")
    module = {
        "identifier": md.coSimulation.modelIdentifier,
        "guid": md.guid,
        "wasm": base64.b64encode(wasm).decode("ascii"),
        "variables": {v.name: [v.valueReference, _kind(v), v.causality] for v in variables if _kind(v)},
        "real_outputs": [v.name for v in outputs if v.type == "Real"],
        "integer_outputs": [v.name for v in outputs if v.type in ("Integer", "Enumeration")],
        "solvers": [[item.name, int(item.value), item.description or ""] for item in solver.declaredType.items]
        if solver is not None and solver.declaredType is not None and solver.type == "Enumeration" else [],
        "defaults": {v.name: _number(v) for v in variables if _kind(v) and v.start is not None},
        # the setting that sets a method's order, where the FMU has it (taylor_order, gbs_columns)
        "order_settings": {method: name for method, name in ORDER_SETTING.items() if name in by_name},
        "energy": next((n for n in ("E", "E_pot") if n in by_name and by_name[n].causality == "output"), None),
        "exact": EXACT.get(md.coSimulation.modelIdentifier),
        "coordinates": [], "points": [], "anchor": None, "spring_ends": [],
    }
    if spec is not None:
        module["coordinates"] = [[c.name, c.velocity, c.unit == "rad"] for c in spec.coordinates]  # angles wrap
        coordinates = set(spec.q)
        # each point: its position outputs by axis, and whether the coordinates move it (a mass or a
        # joint a person can drag, not a driven pivot)
        module["points"] = [{"axes": {axis: p.outputs[axis] for axis in "xyz" if axis in p.outputs},
                             "moves": any(coordinates & e.free_symbols for e in p.position), "mass": p.velocity}
                            for p in spec.points]
        parameters = {p.name for p in spec.parameters}
        module["anchor"] = {axis: f"anchor_{axis}" for axis in "xyz" if f"anchor_{axis}" in parameters} or None
    else:  # an element such as the Spring: drawn between the points that feed its <end>_x, <end>_y inputs
        inputs = {v.name for v in variables if v.causality == "input" and v.type == "Real"}
        module["spring_ends"] = [[name, name[:-2] + "_y"] for name in sorted(inputs)
                                 if name.endswith("_x") and name[:-2] + "_y" in inputs]
    return module


def _shapes(spec: ObjectSpec | None, start: dict) -> list[dict]:
    """Per point of the object: where its string or rod is fixed and how big a ball it is (the object
    file's drawing keys), in numbers for the component's parameters."""
    if spec is None:
        return []
    values = {sp.Symbol(p.name, real=True): float(start.get(p.name, p.start)) for p in spec.parameters}

    def number(expr):
        return float(expr.subs(values)) if expr is not None else None

    return [{"link": [number(e) for e in p.link] if p.link else None, "radius": number(p.radius)}
            for p in spec.points]


def _number(variable) -> float | int:
    value = variable.start
    if variable.type == "Real":
        return float(value)
    if variable.type == "Enumeration" and not re.fullmatch(r"-?\d+", str(value)):
        return int(next(item.value for item in variable.declaredType.items if item.name == value))
    return int(value)


def _payload(system: System, modules: dict[str, dict], keys: dict[Path, str], specs: dict[Path, ObjectSpec | None],
             frame_rate: float) -> dict:
    components = []
    for component in system.components:
        # the start values, encoded as the FMU takes them
        with where(system.origin), where(f"component {component.name!r}"), \
                FmuInstance(component.fmu, name=component.name) as instance:
            start = {name: instance.encode(name, value) for name, value in component.start.items()}
            unknown = [name for name in start if _kind(instance.variables[name]) == ""]
            if unknown:
                raise HarnessError(f"start values of type {instance.variables[unknown[0]].type} ({', '.join(unknown)}) "
                                   "cannot be set in the live view")
        components.append({"name": component.name, "module": keys[component.fmu], "start": start,
                           "traces": [list(pair) for pair in system.traces.get(component.name, [])],
                           "shapes": _shapes(specs[component.fmu], component.start)})
    camera = system.camera
    return {
        "name": system.name, "description": system.description,
        "step": system.step, "stop": system.stop, "frame_rate": frame_rate, "scale": camera.get("scale"),
        "layout": camera.get("layout", "together"),
        "algorithm": "gauss-seidel", "extrapolation": "linear", "max_points": MAX_POINTS,
        "guard": {"share": contact_guard.SHARE, "floor": contact_guard.FLOOR,
                  "steps_per_contact": contact_guard.STEPS_PER_CONTACT, "hertz_duration": contact_guard.HERTZ_DURATION},
        "modules": modules, "components": components,
        "connections": [[c.source, c.output, c.target, c.input] for c in system.connections],
    }


def bundled_script() -> str:
    """web/'s modules as one script for an inline <script type="module">: each file's imports of
    the others dropped and its exports made plain declarations (the files are written so that this
    is all joining them takes)."""
    parts = []
    for name in SCRIPTS:
        text = (WEB / name).read_text()
        text = re.sub(r'^import [^;]*? from "\./[\w.]+\.mjs";\n', "", text, flags=re.MULTILINE)
        text = re.sub(r"^export (?=(async )?(function|class|const|let)\b)", "", text, flags=re.MULTILINE)
        parts.append(f"// ---- web/{name}\n{text}")
    return "\n".join(parts)


def _page(payload: dict) -> str:
    # no "<" at all inside the script element (no </script>, no <!--): JSON's own escape keeps it valid
    scene = json.dumps(payload, separators=(",", ":")).replace("<", "\\u003c")
    script = bundled_script()
    if "</script" in script:
        raise HarnessError("web/: a script holds '</script', which would end the page's script early")
    parts = {"TITLE": html.escape(payload["name"]), "SCENE": scene, "SCRIPT": script}
    return re.sub(r"\{\{(TITLE|SCENE|SCRIPT)\}\}", lambda m: parts[m.group(1)], (WEB / TEMPLATE).read_text())
