"""Command line: a thin layer over the library. User errors print one line and exit with 2."""
from __future__ import annotations

import argparse
import math
import sys
import threading
from pathlib import Path

from harness.cosim.algorithm_registry import DEFAULT as DEFAULT_ALGORITHM, NAMES as ALGORITHM_NAMES
from harness.errors import HarnessError
from harness.fmi.methods import SOLVERS


def _parse_assignment(text: str) -> tuple[str, object]:
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise HarnessError(f"--set expects NAME=VALUE, got {text!r}")
    return name, value  # read by the FMU's variable type: a number, or an enumeration item such as ab4


def positive_number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive finite number")
    return value


def count(largest: int, smallest: int = 1):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if not smallest <= value <= largest:
            raise argparse.ArgumentTypeError(f"{value} must be between {smallest} and {largest}")
        return value
    parse.__name__ = "count"
    return parse


class OneLineParser(argparse.ArgumentParser):
    """argparse, with its usage errors as one line and exit code 2 (help stays as it is)."""

    def error(self, message: str):
        self.exit(2, f"harness: error: {message} (see {self.prog} --help)\n")


def command_simulate(args: argparse.Namespace) -> int:
    from harness.fmi.fmus import locate_fmu
    from harness.fmi.simulation import simulate
    from harness.output import PICTURE_FORMATS, output_file
    out = output_file(args.out, "--out", (args.fmu,))
    plot = output_file(args.plot, "--plot", (args.fmu,), PICTURE_FORMATS, {"--out": out}) if args.plot else None
    start_values = dict(_parse_assignment(a) for a in args.set)
    if args.solver:
        start_values["solver"] = args.solver
    if args.h is not None:
        start_values["h"] = args.h
    pairs = _points_to_draw(locate_fmu(args.fmu)) if plot else []
    result = simulate(locate_fmu(args.fmu), stop_time=args.stop, step=args.step, start_values=start_values,
                      keep_interrupted=True, progress=not args.quiet)
    result.write_csv(out)
    print(f"wrote {out} ({len(result.values)} rows)")
    if result.interrupted:
        raise KeyboardInterrupt
    if plot:
        from harness.scene.traces import draw_traces
        draw_traces([(result.fmu, result, pairs, (0.0, 0.0))], plot)
        print(f"wrote {plot}")
    if result.discarded_at is not None:
        print(f"harness: stopped at t = {result.discarded_at}: {result.messages[-1] if result.messages else ''}",
              file=sys.stderr)
        return 1
    return 0


def _points_to_draw(fmu: Path) -> list[tuple[str, str]]:
    """The (x, y) outputs --plot draws; refused before the run when there are none."""
    from harness.fmi.fmu_instance import read_description
    outputs = [v.name for v in read_description(fmu).modelVariables if v.causality == "output"]
    pairs = plotted_points(fmu, outputs)
    if not pairs:
        raise HarnessError(f"--plot: {fmu.name} has no moving point to draw (no pair of x and y outputs)")
    return pairs


def plotted_points(fmu: Path, columns: list[str]) -> list[tuple[str, str]]:
    """The (x, y) output pairs of the moving points: every point of an object file, else the thesis
    pendulums' bobs; only pairs whose both columns were recorded."""
    from harness.objects.proof import object_file_in
    spec = object_file_in(fmu)
    candidates = ([(p.outputs["x"], p.outputs["y"]) for p in spec.points if {"x", "y"} <= set(p.outputs)]
                  if spec is not None else [("x", "y"), ("x1", "y1"), ("x2", "y2")])
    return [(x, y) for x, y in candidates if x in columns and y in columns]


class StageReport:
    """Names a stage of a long job on stderr once it has taken `delay` seconds: quick jobs print
    nothing, slow ones say what they are busy with."""

    def __init__(self, prefix: str, enabled: bool = True, delay: float = 2.0):
        self.prefix, self.enabled, self.delay = prefix, enabled, delay
        self.timer: threading.Timer | None = None

    def __call__(self, stage: str) -> None:
        self.close()
        if self.enabled:
            self.timer = threading.Timer(self.delay, print, (f"{self.prefix}{stage} ...",),
                                         {"file": sys.stderr, "flush": True})
            self.timer.daemon = True
            self.timer.start()

    def close(self) -> None:
        if self.timer is not None:
            self.timer.cancel()
            self.timer = None


def command_derive(args: argparse.Namespace) -> int:
    from harness.objects.build import derive_fmu
    from harness.output import usable_folder
    report = StageReport(f"{args.object_file}: ", enabled=not args.quiet)
    try:  # the folder is made when the FMUs are written: a refused file leaves none behind
        derived = derive_fmu(args.object_file, usable_folder(args.out, "--out"), report)
    finally:
        report.close()
    print(f"wrote {derived.path} (FMI 2.0) and {derived.fmi3_path} (FMI 3.0)")
    return 0


def command_demo(args: argparse.Namespace) -> int:
    from harness.output import output_folder
    from harness.scene.report import run_demo
    report, index = run_demo(output_folder(args.out, "--out"), args.duration)
    print(f"wrote {index}: {'all verdicts pass' if report.passed else 'some verdicts fail'}")
    return 0 if report.passed else 1


def command_view(args: argparse.Namespace) -> int:
    from harness.view.page import write_view
    page = write_view(args.scene, args.out, args.step)
    sizes = ", ".join(f"{name} {size / 1024:.0f} KB" for name, size in page.modules.items())
    print(f"wrote {page.path} ({page.bytes / 1024:.0f} KB; WebAssembly modules: {sizes}): open it in a browser, "
          f"or serve the folder with python -m http.server")
    return 0


def command_run(args: argparse.Namespace) -> int:
    from harness.cosim.system import component_files, system_inputs
    from harness.cosim.contacts import ContactSteps
    from harness.cosim.master import Master, MasterOptions
    from harness.cosim.system import load_system
    from harness.output import csv_header, output_file, written
    out = output_file(args.out, "--out", system_inputs(args.system))
    reference = output_file(args.reference, "--reference", system_inputs(args.system), outputs={"--out": out}) \
        if args.reference is not None else None
    with load_system(args.system) as system:
        out = output_file(out, "--out", component_files(args.system, system))
        stop = args.stop if args.stop is not None else system.stop
        step = args.step if args.step is not None else system.step
        if stop is None or step is None:
            raise HarnessError(f"{args.system} defines no stop time or step: give --stop and --step")
        scene = None
        if reference is not None:  # refused before the run when the scene has no derived reference
            from harness.studies.monolithic import MonolithicScene
            reference = output_file(reference, "--reference", component_files(args.system, system),
                                    outputs={"--out": out})
            scene = MonolithicScene(system)
        options = MasterOptions(stop=stop, step=step, algorithm=args.algorithm, extrapolation=args.extrapolation,
                                on_discard=args.on_discard, progress=not args.quiet, iterate_tol=args.iterate,
                                tolerance=args.tolerance, energy_tol=args.energy_tolerance,
                                energy_correction=args.energy_correction, contact_steps=args.contact_steps)
        with Master(system, options) as master:
            if scene is not None:  # first: a reference that cannot be written stops the command before --out
                from harness.fmi.simulation import communication_grid
                write_reference(scene, master.columns, communication_grid(options.start, options.stop, options.step),
                                reference)
            with written(out, csv_header(master.columns)) as stream:

                def write_row(row) -> None:  # rows go out as they come: a stopped run keeps what it computed
                    stream.write(",".join(f"{v:.17g}" for v in row) + "\n")

                result = master.run(on_row=write_row)
                landed = isinstance(master.interval, ContactSteps)
    steps = (f"{result.macro_steps} macro steps chosen by step doubling (rows every {step:g} s)" if args.tolerance
             else f"{result.macro_steps} macro steps chosen by the bonds' energy"
                  f"{' and landed on the contacts' if landed else ''} (rows every {step:g} s)"
             if args.energy_tolerance
             else f"{result.macro_steps} macro steps landed on the contacts (rows every {step:g} s)"
             if landed else f"{result.macro_steps} macro steps of {step:g} s")
    print(f"wrote {out}: {steps}, {args.algorithm}, {result.extrapolation} "
          f"extrapolation; energy residual {result.energy_residual:.3e} J"
          + (f", {result.retries} retried steps" if result.retries else "")
          + (f", {result.iterations} iteration passes ({result.unconverged} unconverged)" if args.iterate else "")
          + (f"; the power bonds created {sum(result.bond_energy.values()):.3e} J"
             + (" before correction" if args.energy_correction else "")
             + f" (the energy at the end less that at the start: {result.energy[-1] - result.energy[0]:.3e} J)"
             if result.bond_energy and len(result.energy) else ""))
    if scene is not None:
        print(f"wrote {reference}: the derived monolithic reference ({scene.evaluations} evaluations of its "
              f"{len(scene.start)} states)")
    if result.stopped_at is not None:
        print(f"harness: stopped at t = {result.stopped_at:g}: {result.message}", file=sys.stderr)
        return 1
    return 0


def write_reference(scene, columns: list[str], times, path: Path) -> None:
    """The reference's values at `times` under the run's own column names (those it determines)."""
    import numpy as np

    from harness.output import csv_header, written
    values = scene.solve(times)
    kept = [c for c in columns if c in values]
    with written(path, csv_header(kept)) as stream:
        table = np.column_stack([values[c] for c in kept])
        for row in table:
            stream.write(",".join(f"{v:.17g}" for v in row) + "\n")


def command_export(args: argparse.Namespace) -> int:
    from harness.cosim.system import component_files, system_inputs
    from harness.cosim.scene_file import scene_project_fmus
    from harness.cosim.ssp_export import write_ssp
    from harness.cosim.system import load_system
    from harness.fmi.fmus import build_fmus
    from harness.output import output_file
    out = output_file(args.ssp, "--ssp", system_inputs(args.system), formats=(".ssp",), replaces=".ssp")
    named = scene_project_fmus(args.system)
    if named:  # an export carries them to other machines: every platform's binaries
        build_fmus(named, every_platform=True)
    with load_system(args.system) as system:
        out = output_file(out, "--ssp", component_files(args.system, system), formats=(".ssp",), replaces=".ssp")
        write_ssp(system, out)
    print(f"wrote {out}: {len(system.components)} components, {len(system.connections)} connections"
          + (f", {len(system.bonds)} power bonds" if system.bonds else ""))
    return 0


def command_validate(args: argparse.Namespace) -> int:
    from harness.fmi.fmus import locate_fmu
    from harness.fmi.validation import validate
    failed = 0
    for name in args.fmu:
        path = locate_fmu(name)
        checks = validate(path)
        bad = sum(not c.passed for c in checks)
        failed += bad
        print(f"{path.name}: {len(checks) - bad} of {len(checks)} checks passed")
        for check in checks:
            print(check)
    return 1 if failed else 0


# the scene a chart of a scene takes when --system names none
CHART_SCENES = {"coupling": "coupled_pendulums.json", "contacts": "contact_cradle.json"}


def command_chart(args: argparse.Namespace) -> int:
    from harness.fmi.fmus import build_fmus
    from harness.objects.registry import object_names
    from harness.studies.work_precision import PENDULUMS
    known = list(object_names())
    objects = list(dict.fromkeys(args.objects or (list(PENDULUMS) if args.kind in ("work-precision", "long-run")
                                                  else known)))
    unknown = sorted(set(objects) - set(known))
    if unknown:
        raise HarnessError(f"--objects: {', '.join(unknown)} is not one of {', '.join(known)}")
    if args.methods:
        from harness.studies.work_precision import chart_methods
        if args.kind != "work-precision":
            raise HarnessError(f"--methods: chart {args.kind} takes every method (only work-precision takes some)")
        unknown = sorted(set(args.methods) - set(chart_methods()))
        if unknown:
            raise HarnessError(f"--methods: {', '.join(unknown)} is not one of {', '.join(chart_methods())}")
    from harness.output import output_folder, usable_folder
    usable_folder(args.out, "--out")
    from harness.cosim.scene_file import scene_project_fmus
    from harness.fmi.fmus import PROJECT_ROOT
    scene = args.system or PROJECT_ROOT / "scenes" / CHART_SCENES.get(args.kind, "")
    # the objects' studies take the objects' FMUs, the scenes' (coupling, contacts) the scene's
    build_fmus(scene_project_fmus(scene) if args.kind in CHART_SCENES else objects, programs=["integrator_tables"])
    if args.kind == "work-precision":
        from harness.studies.charts import work_precision_chart
        from harness.studies.work_precision import pareto_front, settings, work_precision, write_csv
        tasks = settings(objects, repeats=args.repeats, quick=args.quick, methods=args.methods)
        if not tasks:
            raise HarnessError(f"--methods: none of {', '.join(args.methods)} runs on {', '.join(objects)}")
    out = output_folder(args.out, "--out")
    if args.kind == "work-precision":
        points = work_precision(tasks, args.scheduler, args.workers)
        write_csv(points, out / "work-precision.csv")
        written = [out / "work-precision.csv", *work_precision_chart(points, out)]
        for name in objects:
            mine = [p for p in points if p.object == name]
            print(f"{name}: Pareto front (evaluations -> error): "
                  + ", ".join(f"{p.method} {p.evaluations} -> {p.error:.1e}" for p in pareto_front(mine)))
            if any(math.isfinite(p.event_error) for p in mine):
                print(f"{name}: Pareto front (evaluations -> event time error): "
                      + ", ".join(f"{p.method} {p.evaluations} -> {p.event_error:.1e} s"
                                  for p in pareto_front(mine, measure="event_error")))
    elif args.kind == "stability":
        from harness.studies.charts import stability_charts
        from harness.fmi.fmus import build_dir
        from harness.studies.stability import atlas, atlas_tables, cases, sharp_deviations, write_csv
        fmu_dir = build_dir() / "fmus"
        limits = atlas(fmu_dir, full=args.full, scheduler=args.scheduler, workers=args.workers, quick=args.quick,
                       objects=objects)
        write_csv(limits, out / "stability.csv")
        written = [out / "stability.csv", *stability_charts(limits, cases(fmu_dir, args.full, args.quick, objects),
                                                            atlas_tables(), out)]
        worst, deviation = max(sharp_deviations(limits, cases(fmu_dir, args.full, args.quick, objects)),
                               key=lambda pair: abs(pair[1]))
        print(f"{len(limits)} limits measured; largest deviation from a sharp prediction (linear cases): "
              f"{deviation:+.2%} ({worst.object}, {worst.method}, d = {worst.damping:.3g}/s)")
    elif args.kind == "long-run":
        from harness.fmi.fmus import build_dir
        from harness.studies.charts import long_run_chart
        from harness.studies.long_run import CASES, PERIODS, long_run, tasks_for, write_csv
        cases = [case for case in CASES if not args.objects or case.object in objects]
        if not cases:
            raise HarnessError(f"--objects: long-run has cases for {', '.join(c.object for c in CASES)}, not for "
                               f"{', '.join(objects)}")
        series = long_run(tasks_for(build_dir() / "fmus", cases, PERIODS // 10 if args.quick else PERIODS),
                          args.scheduler, args.workers)
        write_csv(series, out / "long-run.csv")
        written = [out / "long-run.csv", *long_run_chart(series, out)]
        for case in cases:
            print(f"{case.object} ({case.description}): fitted energy-error slope " + ", ".join(
                f"{s.method} {s.slope:.2f}" for s in series if s.object == case.object))
    elif args.kind == "coupling":
        from harness.studies.charts import coupling_chart
        from harness.studies.coupling import coupling_sweep, write_csv
        from harness.cosim.system import load_system
        with load_system(scene) as system:
            points = coupling_sweep(system, stop=args.stop, repeats=args.repeats, scheduler=args.scheduler,
                                    workers=args.workers)
            title = system.name[:1].upper() + system.name[1:]
        write_csv(points, out / "coupling.csv")
        written = [out / "coupling.csv", *coupling_chart(points, out, title)]
        for name in dict.fromkeys(p.configuration for p in points):
            mine = [p for p in points if p.configuration == name]
            print(f"{name:32s} " + "  ".join(f"H={p.step:g}: {p.error:.1e} m" for p in mine))
    elif args.kind == "contacts":
        from harness.studies.charts import contact_chart
        from harness.studies.contact_study import TARGET, contact_sweep, steps_needed, write_csv
        from harness.cosim.system import load_system
        with load_system(scene) as system:
            points = contact_sweep(system, stop=args.stop, repeats=args.repeats, quick=args.quick,
                                   scheduler=args.scheduler, workers=args.workers)
            title = system.name[:1].upper() + system.name[1:]
        write_csv(points, out / "contacts.csv")
        written = [out / "contacts.csv", *contact_chart(points, out, title)]
        for name, steps in steps_needed(points).items():
            print(f"{name:36s} macro steps at an error of {TARGET:g}: "
                  + (f"{steps:.0f}" if steps == steps else "not bracketed by the runs"))
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def command_plan(args: argparse.Namespace) -> int:
    from harness.cosim.scene_file import scene_project_fmus
    from harness.cosim.system import component_files, system_inputs
    from harness.fmi.fmus import build_fmus
    from harness.studies.planner import plan_scene, write_plan_csv
    from harness.cosim.system import load_system
    from harness.output import output_file
    out = output_file(args.out, "--out", system_inputs(args.scene)) if args.out else None
    build_fmus(scene_project_fmus(args.scene))
    with load_system(args.scene) as system:
        if out is not None:
            out = output_file(out, "--out", component_files(args.scene, system))
        tolerance = args.tolerance
        if args.pixels is not None:
            system.accuracy = {"pixels": args.pixels}
            tolerance = system.tolerance()
        plans = plan_scene(system, tolerance, args.duration, args.scheduler, args.workers, exact=args.exact)
    tolerance = plans[0].tolerance
    duration = args.duration or system.stop
    print(f"{system.name}: {duration:g} s, tolerance {tolerance:.3g} m at every frame "
          f"({1 / system.frame_step():g} per second)")
    print(f"{'object':14s} {'plan':28s} {'predicted':>10s} {'verified':>10s} {'cost':>7s} | "
          f"{'default: rk4, own h':>20s} {'cost':>7s}  verdict")
    for p in plans:
        choice = "linear, closed form" if p.model == "linear" else f"{p.method}, h = {p.h:.4g}"
        if math.isfinite(p.communication_step):
            choice += f", H = {p.communication_step:g}"
        default_ok = p.default_error <= tolerance
        verdict = ("plausible, not pointwise (below)" if p.plan == "plausible" else
                   f"{p.default_cost / p.cost:.1f}x cheaper than the default" if default_ok
                   else "the default misses the tolerance")
        print(f"{p.object:14s} {choice:28s} {p.predicted_error:10.2e} {p.verified_error:10.2e} {p.cost:7d} | "
              f"{p.default_error:20.2e} {p.default_cost:7d}  {verdict}")
    for p in plans:
        if not math.isfinite(p.lyapunov):
            continue
        parting = (f"{p.object}: Lyapunov exponent {p.lyapunov:.3g}/s over the scene, predictability horizon "
                   f"{p.horizon:.3g} s")
        if p.plan == "plausible":
            print(f"{parting} < {duration:g} s: a plausible plan (pointwise accuracy is not to be had at a sensible "
                  f"cost; --exact plans it anyway): energy error {p.energy_error:.2g} J within the "
                  f"{p.energy_limit:.2g} J of one pixel of height, stable, parting like the reference")
        elif p.horizon < duration:
            print(f"{parting} < {duration:g} s, but pointwise" + (" as asked (--exact)" if args.exact else
                                                                 " (no plausible plan: its energy is not conserved "
                                                                 "or no setting keeps it within a pixel)"))
        else:
            print(f"{parting}: pointwise")
    total, default_total = sum(p.cost for p in plans), sum(p.default_cost for p in plans)
    print(f"total cost {total} evaluations against the default's {default_total} ({default_total / total:.2f}x)")
    if out:
        write_plan_csv(plans, out)
        print(f"wrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="harness", description="Pendulum FMUs: simulate, couple, validate, chart.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("simulate", help="simulate one FMU, write CSV (and a trace plot)")
    p.add_argument("fmu", help="a .fmu file (FMI 2.0 or 3.0) or a project FMU: SimplePendulum, DoublePendulum, ... "
                               "(FMI 2.0), fmi3/SimplePendulum, ... (FMI 3.0)")
    p.add_argument("--stop", type=positive_number, default=10.0, help="stop time [s] (default 10)")
    p.add_argument("--step", type=positive_number, default=0.01, help="communication step [s] (default 0.01)")
    p.add_argument("--solver", help=f"integration method, one of {', '.join(SOLVERS)} (default rk4)")
    p.add_argument("--h", type=positive_number, help="internal step [s]")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr during a long run")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="start value or parameter")
    p.add_argument("--out", default="result.csv", help="CSV file to write")
    p.add_argument("--plot", help="picture of the trace of the moving mass (.png, .svg or .pdf)")
    p.set_defaults(run=command_simulate)

    p = sub.add_parser("run", help="co-simulate a system (SSP .ssp/.ssd/folder or a scene .json), write CSV")
    p.add_argument("system", help="an .ssp archive, an .ssd file, a folder with SystemStructure.ssd, or a scene .json")
    p.add_argument("--stop", type=positive_number, help="stop time [s] (default: the system's)")
    p.add_argument("--step", type=positive_number, help="communication step [s] (default: the system's)")
    p.add_argument("--algorithm", choices=ALGORITHM_NAMES, default=DEFAULT_ALGORITHM)
    p.add_argument("--extrapolation", choices=["hold", "linear"],
                   help="inputs over a macro step (default: linear, or hold where a component receives inputs it "
                        "cannot take on a line: an FMI 3.0 FMU whose inputs are not set in intermediate updates)")
    p.add_argument("--on-discard", choices=["stop", "retry"], default="stop",
                   help="after fmi2Discard: stop, or roll back and retry with halved steps")
    p.add_argument("--iterate", type=positive_number, metavar="TOL",
                   help="iterate each macro step (rollback through FMU states) until the outputs change by < TOL")
    p.add_argument("--tolerance", type=positive_number, metavar="TOL",
                   help="adapt the macro step by step doubling so that the coupling error stays below TOL; "
                        "--step is then the output interval and the largest macro step")
    p.add_argument("--energy-tolerance", type=positive_number, metavar="J",
                   help="choose the macro steps by a PI controller on the energy the scene's power bonds create, "
                        "each step's sum of the bonds' |energy| within its share of J over the run (the drift "
                        "then stays below J); on a scene with Contact elements it also lands on each contact's "
                        "onset (as --contact-steps does); --step is then the output interval and the largest "
                        "macro step")
    p.add_argument("--energy-correction", action="store_true",
                   help="hand the energy the power bonds created back through the next steps' forces")
    p.add_argument("--contact-steps", type=count(100_000, 0), metavar="N",
                   help="land macro steps on the onsets of the Contact elements' contacts (rollback through FMU "
                        "states where the prediction fails) and resolve each contact in about N macro steps (with "
                        "--energy-tolerance: no step longer than the energy controller's either); --step is then "
                        "the output interval and the largest macro step. Default: 100 on a scene with Contact "
                        "elements, unless --tolerance, --energy-tolerance or --on-discard retry chooses the steps; "
                        "0: plain macro steps of --step. Whatever the steps, a step that creates more than half the "
                        "energy the scene has in motion stops the run, naming the contact")
    p.add_argument("--out", default="run.csv", help="CSV file: time and <component>.<output> columns")
    p.add_argument("--reference", metavar="FILE.csv",
                   help="also write the scene's derived monolithic solution (objects joined by Springs and Contacts) "
                        "at the same communication points, under the same column names, for every state and output "
                        "it determines")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=command_run)

    p = sub.add_parser("export", help="write a system (scene .json or SSP) as an SSP 1.0 archive for other importers")
    p.add_argument("system", help="a scene .json, an .ssp archive, an .ssd file or a folder with SystemStructure.ssd")
    p.add_argument("--ssp", required=True, metavar="FILE.ssp", help="the archive to write")
    p.set_defaults(run=command_export)

    p = sub.add_parser("validate", help="check FMUs: fmpy validation, runtime conformance, physics and numerics")
    p.add_argument("fmu", nargs="+", help=".fmu files or the project's FMU names")
    p.set_defaults(run=command_validate)

    p = sub.add_parser("chart", help="sweeps and their charts: work-precision, stability, long-run, coupling, contacts")
    p.add_argument("kind", choices=["work-precision", "stability", "long-run", "coupling", "contacts"],
                   help="which sweep")
    p.add_argument("--out", default="charts", help="output folder for the CSV and the PNG/SVG charts")
    p.add_argument("--objects", nargs="+", metavar="NAME", help="objects to include, any of the registry's "
                   "(default: work-precision and long-run the three thesis pendulums, stability every object with a "
                   "linear model)")
    p.add_argument("--quick", action="store_true", help="work-precision and stability: every other step, "
                   "tolerance and damping ratio; long-run: 1,000 periods instead of 10,000 (a chart in seconds); "
                   "contacts: no fixed step below 2e-6 s and at most 200 steps per contact")
    p.add_argument("--repeats", type=count(1000), default=3,
                   help="timed repeats per point; the median is kept (default 3)")
    p.add_argument("--methods", nargs="+", metavar="NAME", help="work-precision: only these methods and peers "
                   "(the FMUs' methods, scipy-RK45, scipy-DOP853, scipy-LSODA, fmpy-CVode; default: all)")
    p.add_argument("--scene", "--system", dest="system",
                   help="coupling: a scene of objects joined by Springs (default scenes/coupled_pendulums.json); "
                        "contacts: one with Contact elements (default scenes/contact_cradle.json)")
    p.add_argument("--stop", type=positive_number, help="coupling and contacts: simulated time [s] (default: the "
                                                        "system's)")
    p.add_argument("--full", action="store_true", help="stability: the full atlas (19 damping ratios instead of 8)")
    p.add_argument("--workers", type=count(256), help="parallel worker processes (default: all local cores)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the sweep on a Dask cluster: 'local' starts one here, HOST:PORT uses a running one")
    p.set_defaults(run=command_chart)

    p = sub.add_parser("plan", help="choose model, method and step per object for a scene's accuracy")
    p.add_argument("scene", help="a scene file (.json) with objects, duration and accuracy")
    p.add_argument("--tolerance", type=positive_number, help="position tolerance [m] (default: the scene's accuracy)")
    p.add_argument("--pixels", type=positive_number, help="tolerance in pixels, through the scene camera's scale")
    p.add_argument("--duration", type=positive_number, help="scene duration [s] (default: the scene's stop)")
    p.add_argument("--exact", action="store_true", help="pointwise plans also for objects whose motion parts "
                   "faster than the scene lasts (default: a plausible plan for those)")
    p.add_argument("--out", help="CSV file for the plan")
    p.add_argument("--workers", type=count(256), help="parallel worker processes (default: all local cores)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="plan on a Dask cluster ('local' or HOST:PORT)")
    p.set_defaults(run=command_plan)

    p = sub.add_parser("derive", help="an object file (T, U, points, forces) -> DIR/<identifier>.fmu (FMI 2.0) "
                                       "and DIR/fmi3/<identifier>.fmu (FMI 3.0)")
    p.add_argument("object_file", help="the object's .toml file")
    p.add_argument("--out", default=".", help="folder for the FMU (default: the current one)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(run=command_derive)

    p = sub.add_parser("view", help="the scene live in a browser: DIR/index.html, self-contained (drag, pause, step, "
                                     "methods; index.html?check=T runs T seconds headless)")
    p.add_argument("scene", help="a scene file (.json) or an SSP (.ssp, .ssd, folder)")
    p.add_argument("--out", default="view", help="folder for index.html (default view/)")
    p.add_argument("--step", type=positive_number, help="communication step [s] (default: the scene's)")
    p.set_defaults(run=command_view)

    p = sub.add_parser("demo",
                       help="the main job: thesis scene, coupled scene, plan, validation, charts -> DIR/index.html")
    p.add_argument("--out", default="out", help="output folder (default out/)")
    p.add_argument("--duration", type=positive_number,
                   help="simulated and planned time of the thesis scene [s] (default: the scene's, 20)")
    p.set_defaults(run=command_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    """The error boundary: a user error is one line and exit code 2, a stopped simulation exit code 1
    (its rows kept), an interrupt (Ctrl-C or SIGTERM) exit code 130 with rows kept and temporary
    files removed. Anything else is a fault of the harness: one line, exit code 3, and the
    traceback only with PENDULUM_TRACEBACK=1."""
    import os
    import warnings

    from harness import interrupts
    # the first Ctrl-C or SIGTERM interrupts, never inside an FMU's callback, an import or a held
    # section; later ones are ignored, so that the clean-up they started (rows kept, temporary files
    # removed, workers ended) is not cut short (harness/interrupts.py)
    installed = interrupts.install()
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as stop:  # usage errors (2) and --help (0): returned, as every other outcome
            return stop.code if isinstance(stop.code, int) else 2
        with warnings.catch_warnings():
            if os.environ.get("PENDULUM_TRACEBACK") != "1":  # numpy's and matplotlib's notes are not for users
                warnings.simplefilter("ignore")
            return args.run(args)
    except HarnessError as error:
        return _report("error", str(error), 2)
    except KeyboardInterrupt:
        print("harness: interrupted", file=sys.stderr)
        return 130
    except RecursionError:
        return _report("error", "input nested too deeply", 2)
    except MemoryError:
        return _report("error", "not enough memory for this run (choose a larger step or a shorter time)", 2)
    except OSError as error:
        where = f"{error.filename}: " if error.filename else ""
        return _report("error", f"{where}{error.strerror or error}", 2)
    except Exception as error:  # a fault of the harness, not of the input: say so in one line
        if isinstance(error, RuntimeError) and str(error).startswith("Symlink loop"):  # pathlib's, in Python 3.11
            return _report("error", f"{error} (a loop of symbolic links)", 2)
        if os.environ.get("PENDULUM_TRACEBACK") == "1":
            raise
        return _report("internal error", f"{type(error).__name__}: {error} (set PENDULUM_TRACEBACK=1 for the "
                       "traceback and report it)", 3)
    finally:
        if installed:
            interrupts.uninstall()


def _report(kind: str, text: str, code: int) -> int:
    lines = text.strip().splitlines() or ["(no detail)"]
    print(f"harness: {kind}: {lines[0]}" + (" [...]" if len(lines) > 1 else ""), file=sys.stderr)
    return code
