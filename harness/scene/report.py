"""The demo: the whole project on the thesis scene in one command, written to DIR/index.html.

Runs the thesis scene (traces, animation), the coupled scene (against its monolithic reference),
plans the thesis scene for its visual tolerance, validates the FMUs, and draws the work-precision
and stability charts of the thesis pendulums at quick settings; every section ends in a verdict.
"""
from __future__ import annotations

import html
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

from harness.fmi.fmus import PROJECT_ROOT, build_dir, build_fmus, locate_fmu
from harness.output import written


@dataclass
class Section:
    title: str
    verdict: str
    passed: bool
    body: str  # HTML
    seconds: float = 0.0


@dataclass
class Report:
    sections: list[Section] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return all(s.passed for s in self.sections)


def _table(header: list[str], rows: list[list]) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _image(name: str, alt: str) -> str:
    return f'<p><img src="{html.escape(name)}" alt="{html.escape(alt)}"></p>'


def thesis_section(out: Path, duration: float | None) -> Section:
    from harness.scene.thesis_scene import load_thesis_scene, run_thesis_scene
    system = load_thesis_scene()
    results = run_thesis_scene(out, duration)
    rows, ok = [], True
    for name, result in results.items():
        energy = result["E"]
        drift = abs(energy[-1] - energy[0]) / max(abs(energy[0]), float(result["E_kin"].max()))
        status = "ok" if result.discarded_at is None else f"fmi2Discard at t = {result.discarded_at:.3f} s"
        ok &= result.discarded_at is None
        start = system.component(name).start
        rows.append([name, result.fmu, start.get("solver", "rk4"), start.get("h"), int(result["n_rhs"][-1]),
                     f"{drift:.2e}", status])
    body = (_table(["object", "FMU", "method", "h [s]", "evaluations", "energy drift / max E_kin", "run"], rows)
            + _live_view(out) + _image("thesis_scene_traces.png", "traces") + _image("thesis_scene.gif", "animation"))
    verdict = (f"all {len(rows)} objects ran {duration or system.stop:g} s at the thesis's step widths"
               if ok else "an object stopped early")
    return Section("Thesis scene (appendix C.2, figures C.1-C.3)", verdict, ok, body)


def _live_view(out: Path) -> str:
    """The thesis scene live in the browser (harness view), at live/index.html, and the link to it; where
    the WebAssembly tools are missing, why there is none (the scene's verdict does not depend on it)."""
    from harness.errors import HarnessError
    from harness.scene.thesis_scene import THESIS_SCENE_FILE
    from harness.view.page import write_view
    try:
        page = write_view(THESIS_SCENE_FILE, out / LIVE_FOLDER)
    except HarnessError as error:
        return f"<p>No live view: {html.escape(str(error))}</p>"
    return (f"<p><b><a href='{LIVE_FOLDER}/index.html'>The scene live</a></b>: the same FMUs built to WebAssembly "
            f"({', '.join(f'{n} {b / 1024:.0f} KB' for n, b in page.modules.items())}) in one self-contained "
            "page; drag a mass to start it from there, pause, step, choose each object's method and step, and watch "
            "the energies and the simple pendulum's error against its exact solution.</p>")


LIVE_FOLDER = "live"


def coupled_section(out: Path) -> Section:
    from harness.studies.coupling import coupling_error, derived_reference
    from harness.cosim.master import MasterOptions, run_system
    from harness.cosim.system import load_system
    from harness.scene.traces import draw_traces
    system = load_system(PROJECT_ROOT / "scenes" / "coupled_pendulums.json")
    rows, ok = [], True
    reference = None
    for algorithm, extrapolation in (("jacobi", "hold"), ("gauss-seidel", "linear")):
        result = run_system(system, MasterOptions(stop=system.stop, step=system.step, algorithm=algorithm,
                                                  extrapolation=extrapolation))
        reference = reference or derived_reference(system, result.time)
        error = coupling_error(result, *reference)
        rows.append([f"{algorithm}, {extrapolation}", f"{system.step:g}", f"{error:.2e}",
                     f"{result.energy_residual:.2e}"])
        if algorithm == "gauss-seidel":
            result.write_csv(out / "coupled_pendulums.csv")
            draw_traces([("coupled pendulums (Gauss-Seidel, linear)", result, [("left.x", "left.y"),
                                                                              ("right.x", "right.y")], (0.0, 0.0))],
                        out / "coupled_traces.png")
            ok = error < 1e-2
    body = (_table(["master", "H [s]", "largest bob error against the monolithic reference [m]",
                    "energy residual [J]"], rows) + _image("coupled_traces.png", "coupled traces"))
    verdict = f"Gauss-Seidel with linear extrapolation within {float(rows[-1][2]):.1e} m of the monolithic reference"
    return Section("Coupled pendulums (two FMUs and a Spring FMU, co-simulated)", verdict, ok, body)


def plan_section(out: Path, duration: float | None = None) -> Section:
    from harness.studies.planner import plan_scene, write_plan_csv
    from harness.scene.thesis_scene import load_thesis_scene
    system = load_thesis_scene()
    plans = plan_scene(system, duration=duration)
    write_plan_csv(plans, out / "plan.csv")
    tolerance = plans[0].tolerance
    rows = [[p.object, "linear, closed form" if p.model == "linear" else p.method, f"{p.h:.4g}",
             f"{p.predicted_error:.2e}", f"{p.verified_error:.2e}", p.cost, f"{p.default_error:.2e}", p.default_cost,
             "meets" if p.default_error <= tolerance else "misses",
             f"{p.horizon:.3g}" if math.isfinite(p.horizon) else "", p.plan] for p in plans]
    pointwise = [p for p in plans if p.plan == "pointwise"]
    plausible = [p for p in plans if p.plan == "plausible"]
    ok = all(p.verified_error <= tolerance and (p.default_error > tolerance or p.cost <= p.default_cost)
             for p in pointwise) and all(p.energy_error <= p.energy_limit for p in plausible)
    total, default = sum(p.cost for p in plans), sum(p.default_cost for p in plans)
    verdict = (f"{len(pointwise)} objects within {system.accuracy.get('pixels', '')} pixel ({tolerance * 1000:.1f} mm) "
               f"at every frame for {duration or system.stop:g} s"
               + "".join(f", {p.object} plausible (horizon {p.horizon:.3g} s; energy within one pixel of height)"
                         for p in plausible)
               + f"; {total} evaluations against the default's {default}")
    body = _table(["object", "plan", "h [s]", "predicted [m]", "verified [m]", "cost", "default error [m]",
                   "default cost", "default", "horizon [s]", "kind"], rows)
    return Section(f"Plan for the thesis scene at {tolerance * 1000:.1f} mm", verdict, ok, body)


def validation_section() -> Section:
    from harness.studies.sweep import run_sweep
    from harness.fmi.validation import validate
    checks = run_sweep(validate, [locate_fmu(name) for name in demo_fmus()])
    rows = [[c.fmu, c.name, "PASS" if c.passed else "FAIL", c.detail] for group in checks for c in group]
    failed = sum(row[2] == "FAIL" for row in rows)
    return Section("Validation (fmpy rules, runtime conformance, physics, numerics)",
                   f"{len(rows) - failed} of {len(rows)} checks passed", failed == 0,
                   _table(["FMU", "check", "result", "detail"], rows))


def interactive_chart(stem: str, alt: str) -> str:
    """A chart as its SVG, whose points name their method and setting when hovered (a <title> each: no
    script, nothing from the network), with the PNG inside for a browser that shows no SVG."""
    return (f'<p><object class="chart" data="{html.escape(stem)}.svg" type="image/svg+xml">'
            f'<img src="{html.escape(stem)}.png" alt="{html.escape(alt)}"></object></p>')


def charts_section(out: Path) -> Section:
    from harness.studies.charts import stability_charts, work_precision_chart
    from harness.studies.stability import atlas, atlas_tables, cases, sharp_deviations
    from harness.studies.stability import write_csv as write_limits
    from harness.studies.work_precision import PENDULUMS, pareto_front, settings, work_precision
    from harness.studies.work_precision import write_csv as write_points
    points = work_precision(settings(repeats=1, quick=True))
    write_points(points, out / "work-precision.csv")
    work_precision_chart(points, out)
    fmu_dir = build_dir() / "fmus"
    # the thesis pendulums, as the work-precision chart (`harness chart stability` charts every object)
    limits = atlas(fmu_dir, quick=True, objects=list(PENDULUMS))
    write_limits(limits, out / "stability.csv")
    # the regions of the methods as the atlas measured them (taylor and gbs at its orders)
    thesis_cases = cases(fmu_dir, quick=True, objects=list(PENDULUMS))
    stability_charts(limits, thesis_cases, atlas_tables(), out)
    worst = max(abs(deviation) for _, deviation in sharp_deviations(limits, thesis_cases))
    fronts = [[name, ", ".join(f"{p.method} ({p.evaluations} -> {p.error:.0e} m)"
                               for p in pareto_front([q for q in points if q.object == name])[-4:])]
              for name in PENDULUMS]
    body = ("<p>A panel per object and method family, the other families grey behind it and the Pareto front of "
            "all methods in black. Hover a point for its method, its setting, its error and its cost.</p>"
            + interactive_chart("work-precision", "work-precision: error against evaluations")
            + _table(["object", "cheapest most accurate points"], fronts)
            + interactive_chart("work-precision-time", "work-precision: error against run time")
            + interactive_chart("stability-regions", "stability regions")
            + interactive_chart("stability-limits", "stability limits"))
    return Section("Speed against accuracy (quick settings)",
                   f"{len(points)} work-precision points; {len(limits)} stability limits, those with a sharp "
                   f"prediction within {worst:.1%} of it", worst < 0.05, body)


STYLE = """body{font-family:sans-serif;max-width:1200px;margin:2em auto;color:#222}
table{border-collapse:collapse;margin:1em 0;font-size:13px}td,th{border:1px solid #ccc;padding:3px 8px}
th{background:#f0f0f0}img{max-width:100%}
object.chart{width:100%;max-width:1000px}.pass{color:#1a7f37}.fail{color:#c62828}h2{margin-top:2em}"""


def write_index(report: Report, out: Path, seconds: float) -> Path:
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Pendulum FMUs: demo</title>"
             f"<style>{STYLE}</style></head><body><h1>Pendulum FMUs: demo report</h1>",
             f"<p class='{'pass' if report.passed else 'fail'}'>"
             f"<b>{'All verdicts pass' if report.passed else 'Some verdicts fail'}"
             f"</b> ({seconds:.0f} s)</p><ul>"]
    for s in report.sections:
        parts.append(f"<li class='{'pass' if s.passed else 'fail'}'>{'PASS' if s.passed else 'FAIL'}: "
                     f"{html.escape(s.title)}: {html.escape(s.verdict)}</li>")
    parts.append("</ul>")
    for s in report.sections:
        parts.append(f"<h2>{html.escape(s.title)}</h2><p class='{'pass' if s.passed else 'fail'}'>"
                     f"<b>{'PASS' if s.passed else 'FAIL'}</b>: {html.escape(s.verdict)} ({s.seconds:.0f} s)</p>"
                     f"{s.body}")
    parts.append("</body></html>")
    path = out / "index.html"
    with written(path) as sink:
        sink.write("\n".join(parts))
    return path


DEMO_SCENES = ("thesis_scene.json", "coupled_pendulums.json")


def demo_fmus() -> list[str]:
    """The FMUs the demo's scenes name: what it builds, runs and validates (`harness validate` takes any)."""
    from harness.cosim.scene_file import scene_project_fmus
    return list(dict.fromkeys(name for scene in DEMO_SCENES
                              for name in scene_project_fmus(PROJECT_ROOT / "scenes" / scene)))


def run_demo(out: Path, duration: float | None = None, progress=print) -> tuple[Report, Path]:
    # only what the demo shows, for this machine: a first demo waits on no other object or platform
    progress(f"building {', '.join(demo_fmus())} and the harness's C loops (if needed) ...")
    build_fmus(demo_fmus(), programs=["integrator_tables"])
    out.mkdir(parents=True, exist_ok=True)
    report, start = Report(), time.perf_counter()
    steps = [lambda: thesis_section(out, duration), lambda: coupled_section(out), lambda: plan_section(out, duration),
             validation_section, lambda: charts_section(out)]
    for step in steps:
        began = time.perf_counter()
        section = step()
        section.seconds = time.perf_counter() - began
        report.sections.append(section)
        progress(f"{'PASS' if section.passed else 'FAIL'}  {section.title}: {section.verdict} "
                 f"({section.seconds:.0f} s)")
    return report, write_index(report, out, time.perf_counter() - start)
