"""The scene of thesis appendix C.2 (`scenes/thesis_scene.json`) and its figures C.1-C.3: each object
run alone with its own step width, the trace pictures, and an animation of the whole scene."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from harness.cosim.system import System, load_system
from harness.errors import HarnessError
from harness.fmi.fmus import PROJECT_ROOT
from harness.fmi.simulation import SimulationResult, simulate
from harness.output import written
from harness.scene.traces import draw_traces

THESIS_SCENE_FILE = PROJECT_ROOT / "scenes" / "thesis_scene.json"


def load_thesis_scene(path: str | Path = THESIS_SCENE_FILE) -> System:
    return load_system(path)


def anchor(system: System, name: str) -> tuple[float, float]:
    start = system.component(name).start
    return float(start.get("anchor_x", 0.0)), float(start.get("anchor_y", 0.0))


def traces_of(system: System, name: str) -> list[tuple[str, str]]:
    return list(system.traces.get(name, [("x", "y")]))


def run_scene_objects(system: System, duration: float | None = None, out: Path | None = None,
                      start_overrides: dict[str, dict] | None = None) -> dict[str, SimulationResult]:
    """Each object alone (a scene without connections), recorded at its own internal step h, the
    thesis's frame interval; <name>.csv into out when given."""
    if system.connections:
        raise HarnessError(f"{system.name}: objects are run alone here; use `harness run` for a coupled system")
    duration = duration if duration is not None else system.stop
    if duration is None:
        raise HarnessError(f"{system.name}: no duration (\"stop\") given")
    results = {}
    for component in system.components:
        values = dict(component.start, **(start_overrides or {}).get(component.name, {}))
        step = float(values.get("h", system.frame_step() or 0.01))
        results[component.name] = simulate(component.fmu, stop_time=duration, step=step, start_values=values)
        if out is not None:
            results[component.name].write_csv(out / f"{component.name}.csv")
    return results


def draw_scene_traces(system: System, results: dict[str, SimulationResult], out: Path) -> list[Path]:
    """One picture with every object (like figures C.1-C.3 side by side) and one per object."""
    def title(name: str) -> str:
        start = system.component(name).start
        return f"{name}: {system.component(name).fmu.stem}, {start.get('solver', 'rk4')}, h = {start.get('h')}"
    panels = [(title(name), results[name], traces_of(system, name), anchor(system, name)) for name in results]
    paths = [out / "thesis_scene_traces.png"]
    draw_traces(panels, paths[0])
    for panel in panels:
        name = panel[0].split(":")[0]
        paths.append(out / f"{name}_trace.png")
        draw_traces([panel], paths[-1])
    return paths


PANEL = 240  # pixels per panel side
COLOURS = ((31, 119, 180), (214, 39, 40))  # trace colours: outer mass last


def animate_scene(system: System, results: dict[str, SimulationResult], path: Path, frame_rate: float = 25.0,
                  duration: float | None = None) -> Path:
    """A GIF of the whole scene: one panel per object, the links drawn at each frame and the masses'
    traces growing behind them. Drawn with Pillow straight into pixels (a trace segment per frame on a
    layer that keeps them), so a 20 s scene takes seconds. Positions between recorded points are
    interpolated linearly, for display only."""
    from PIL import Image, ImageDraw

    names = list(results)
    end = min(r.time[-1] for r in results.values())
    if duration is not None:
        end = min(end, duration)
    frames = np.arange(0.0, end + 1e-9, 1.0 / frame_rate)
    panels = []
    for k, name in enumerate(names):
        result, pivot = results[name], anchor(system, name)
        points = [(np.interp(frames, result.time, result[x]), np.interp(frames, result.time, result[y]))
                  for x, y in traces_of(system, name)]
        xs = np.concatenate([p[0] for p in points] + [[pivot[0]]])
        ys = np.concatenate([p[1] for p in points] + [[pivot[1]]])
        span = 1.15 * max(np.ptp(xs), np.ptp(ys), 0.5)
        centre = ((xs.max() + xs.min()) / 2, (ys.max() + ys.min()) / 2)
        scale = (PANEL - 20) / span

        def pixel(x, y, centre=centre, scale=scale, offset=k * PANEL):
            return offset + PANEL / 2 + (x - centre[0]) * scale, PANEL / 2 + 8 - (y - centre[1]) * scale
        panels.append((name, points, pixel, pivot))
    width = PANEL * len(names)
    traces = Image.new("RGB", (width, PANEL + 16), "white")
    pen = ImageDraw.Draw(traces)
    for name, _, pixel, pivot in panels:
        pen.text((pixel(*pivot)[0] - 4 * len(name), 2), name, fill="black")
        px, py = pixel(*pivot)
        pen.polygon([(px, py - 5), (px - 5, py + 4), (px + 5, py + 4)], fill="black")
    images = []
    for i, t in enumerate(frames):
        for _, points, pixel, _ in panels:
            for j, (x, y) in enumerate(points):
                if i:
                    pen.line([pixel(x[i - 1], y[i - 1]), pixel(x[i], y[i])],
                             fill=COLOURS[min(j + 2 - len(points), 1)], width=1)
        frame = traces.copy()
        draw = ImageDraw.Draw(frame)
        for _, points, pixel, pivot in panels:
            chain = [pixel(*pivot)] + [pixel(x[i], y[i]) for x, y in points]
            draw.line(chain, fill="black", width=3)
            for cx, cy in chain[1:]:
                draw.ellipse([cx - 5, cy - 5, cx + 5, cy + 5], fill=(60, 60, 60))
        draw.text((4, PANEL + 2), f"t = {t:5.2f} s", fill="black")
        images.append(frame.quantize(colors=32, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE))
    buffer = io.BytesIO()
    images[0].save(buffer, format="GIF", save_all=True, append_images=images[1:], duration=round(1000 / frame_rate),
                   loop=0, optimize=False)
    with written(Path(path), binary=True) as sink:
        sink.write(buffer.getvalue())
    return path


def run_thesis_scene(out: Path, duration: float | None = None, animation: bool = True) -> dict[str, SimulationResult]:
    """Simulates every object, writes <name>.csv, the trace pictures and (optionally) the animation into out."""
    out.mkdir(parents=True, exist_ok=True)
    system = load_thesis_scene()
    results = run_scene_objects(system, duration, out)
    draw_scene_traces(system, results, out)
    if animation:
        animate_scene(system, results, out / "thesis_scene.gif", system.camera.get("frame_rate", 25.0))
    return results
