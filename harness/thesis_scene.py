"""The scene of thesis appendix C.2 and its figures C.1-C.3: what the demo runs."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from harness.fmus import locate_fmu
from harness.simulation import SimulationResult, simulate
from harness.traces import draw_traces


@dataclass(frozen=True)
class SceneObject:
    name: str
    fmu: str
    step: float  # the thesis's step width: internal step h and frame interval alike
    start_values: dict = field(default_factory=dict)
    traces: tuple = (("x", "y"),)

    @property
    def anchor(self) -> tuple[float, float]:
        return self.start_values.get("anchor_x", 0.0), self.start_values.get("anchor_y", 0.0)


LINK = 0.9  # both links of the double pendulum, modelled as uniform rods
THESIS_SCENE = (
    SceneObject("simple", "SimplePendulum", 0.008, {"L": 1.0, "phi": 0.5}),
    SceneObject("spring_D34", "SpringPendulum", 0.05,
                {"anchor_y": 0.7, "l0": 1.4, "D": 34.0, "phi": 0.75 * math.pi}),
    SceneObject("spring_D104", "SpringPendulum", 0.05,
                {"anchor_y": 0.7, "l0": 1.4, "D": 104.0, "phi": 0.75 * math.pi}),
    SceneObject("double", "DoublePendulum", 0.04,
                {"anchor_y": LINK, "l1": LINK, "l2": LINK, "s1": LINK / 2, "s2": LINK / 2,
                 "J1": LINK ** 2 / 12, "J2": LINK ** 2 / 12, "phi1": math.pi / 2, "phi2": math.pi / 2},
                (("x1", "y1"), ("x2", "y2"))),
)


def run_thesis_scene(out: Path, duration: float = 20.0, solver: str = "rk4") -> dict[str, SimulationResult]:
    """Simulates every object, writes <name>.csv and the trace pictures into out."""
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    for obj in THESIS_SCENE:
        values = {"solver": solver, "h": obj.step, **obj.start_values}
        result = simulate(locate_fmu(obj.fmu), stop_time=duration, step=obj.step, start_values=values)
        result.write_csv(out / f"{obj.name}.csv")
        results[obj.name] = result
    panels = [(f"{obj.name}: {obj.fmu}, h = {obj.step}", results[obj.name], list(obj.traces), obj.anchor)
              for obj in THESIS_SCENE]
    draw_traces(panels, out / "thesis_scene_traces.png")
    for title, result, pairs, anchor in panels:
        name = title.split(":")[0]
        draw_traces([(title, result, pairs, anchor)], out / f"{name}_trace.png")
    return results
