"""Charts of the sweeps (matplotlib, written as PNG and SVG).

Each panel draws a few coloured lines: the methods of one family (`harness.fmi.methods.FAMILIES`, the
peers as one more), with every other method faint grey behind them for comparison and the Pareto
front in black over them. Legends sit outside the axes, every axis names its unit, and the figures
are sized to be read at a README's width (about 900 pixels for 10 inches). The SVG files are the
interactive versions: each point carries a <title> naming its method and setting, which a browser
shows on hover, and nothing in them is loaded from elsewhere.

`python -m harness.studies.charts FOLDER ...` draws the charts again from the CSV files in each
FOLDER, without running the sweeps.
"""
from __future__ import annotations

import html
import io
import math
import re
import statistics
import sys
from pathlib import Path

import matplotlib
import matplotlib.colors
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from harness.errors import HarnessError  # noqa: E402
from harness.fmi.methods import FAMILIES, METHOD, METHODS  # noqa: E402
from harness.output import write_figure, written  # noqa: E402
from harness.studies.work_precision import STEP, STOP, Point, pareto_front  # noqa: E402

WIDTH = 10.0  # inches: shown about 900 pixels wide, a 8-point font stays about 10 pixels high
DPI = 180     # the PNG at twice that width, sharp on dense screens
GRID_COLUMNS = 3  # objects side by side; more objects continue in a block below
MOST_LINES = 7  # coloured lines in any panel: the largest family (one-step Runge-Kutta)
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2")  # tab10 without grey
MARKERS = "os^vDPX"
CONTEXT = "#cccccc"  # the other families' methods, behind
BAND = "#e6e6e6"     # below the reference's own error
PEERS = ("peers", "peers: scipy's solve_ivp, fmpy's CVode")
SVG_SALT = "pendulum-charts"  # fixed ids and no date: a chart drawn again from the same data is the same file


def family_of(method: str) -> str:
    return METHOD[method].family if method in METHOD else PEERS[0]


def method_families(methods) -> list[tuple[str, str, list[str]]]:
    """(key, label, methods) for every family with a method among `methods`, in FAMILIES' order and
    each family's methods in METHODS' order (the peers last, as they come)."""
    present = list(dict.fromkeys(methods))
    ordered = [m.name for m in METHODS if m.name in present] + [m for m in present if m not in METHOD]
    groups = []
    for key, label in (*FAMILIES, PEERS):
        mine = [m for m in ordered if family_of(m) == key]
        if mine:
            groups.append((key, label, mine))
    return groups


def method_style(method: str, peers: list[str] = ()) -> dict:
    """A method's colour and marker: by its place in its family, so the same in every chart."""
    members = [m.name for m in METHODS if m.family == family_of(method)] if method in METHOD else list(peers)
    k = members.index(method) if method in members else 0
    return {"color": COLOURS[k % len(COLOURS)], "marker": MARKERS[k % len(MARKERS)]}


class Tooltips:
    """Hover texts for a figure's SVG: each artist given one is drawn inside an SVG group of its own id,
    and `apply` puts a <title> with the text into that group (the browser's tooltip; no script)."""

    def __init__(self, prefix: str):
        self.prefix = prefix
        self.texts: dict[str, str] = {}

    def attach(self, artist, text: str, kind: str = "tip"):
        """kind: "tip" for a point, "curve" for a line (hovered anywhere along it)."""
        gid = f"{self.prefix}-{kind}{len(self.texts)}"
        artist.set_gid(gid)
        self.texts[gid] = text
        return artist

    def point(self, ax, x: float, y: float, text: str, **style):
        artist, = ax.plot([x], [y], linestyle="none", **style)
        return self.attach(artist, text)

    def apply(self, svg: str) -> str:
        for gid, text in self.texts.items():
            opening = f'<g id="{gid}">'
            if svg.count(opening) != 1:
                raise HarnessError(f"chart {self.prefix}: the point {gid} is not in the SVG once")
            svg = svg.replace(opening, f"{opening}<title>{html.escape(text)}</title>")
        return svg


def svg_of(figure, tips: Tooltips | None = None) -> str:
    """The figure as SVG text with its tooltips."""
    buffer = io.StringIO()
    with plt.rc_context({"svg.hashsalt": SVG_SALT}):
        figure.savefig(buffer, format="svg", metadata={"Date": None, "Creator": None, "Format": None, "Type": None})
    # The DOCTYPE names a DTD by its web address; nothing needs it, and a chart that works offline
    # should name no web address at all.
    svg = re.sub(r"<!DOCTYPE[^>]*>\s*", "", buffer.getvalue())
    return tips.apply(svg) if tips else svg


def save(figure, out: Path, stem: str, tips: Tooltips | None = None) -> list[Path]:
    paths = [out / f"{stem}.png", out / f"{stem}.svg"]
    write_figure(figure, paths[0], dpi=DPI)
    # the SVG keeps the PNG's layout: laying out again costs as much as the drawing and moves panels by up
    # to 1.5% of the figure (text is measured at another resolution)
    figure.set_layout_engine("none")
    with written(paths[1]) as sink:
        sink.write(svg_of(figure, tips))
    plt.close(figure)
    return paths


def log_axes(ax) -> None:
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(matplotlib.ticker.LogLocator(numticks=6))
    for axis in (ax.xaxis, ax.yaxis):  # a mark per decade: 2, 3, ..., 9 as well cost a third of a chart's drawing
        axis.set_minor_locator(matplotlib.ticker.LogLocator(subs=(1.0,), numticks=100))
        axis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.grid(True, which="major", alpha=0.3)
    ax.tick_params(labelsize=7.5)


def family_grid(objects: list[str], groups, xlabel: str, ylabel: str, panel_height: float = 1.55):
    """A panel per object (column) and family (row), blocks of GRID_COLUMNS objects one below the other;
    an object's panels share their axes. The family's legend goes right of its row, outside the axes,
    once its lines are drawn (`family_legends`). Returns the figure, {(object, family key): axes} and the
    blocks (lists of objects)."""
    blocks = [objects[i:i + GRID_COLUMNS] for i in range(0, len(objects), GRID_COLUMNS)]
    columns, rows = min(GRID_COLUMNS, len(objects)), len(groups) * len(blocks)
    figure = plt.figure(figsize=(WIDTH, 0.9 + rows * panel_height), layout="constrained")
    grid = figure.subplots(rows, columns, squeeze=False)
    panels = {}
    for b, block in enumerate(blocks):
        for column in range(columns):
            for r, (key, _, _) in enumerate(groups):
                ax = grid[b * len(groups) + r][column]
                if column >= len(block):
                    ax.axis("off")
                    continue
                name = block[column]
                panels[(name, key)] = ax
                first = panels[(name, groups[0][0])]
                if ax is not first:
                    ax.sharex(first)
                    ax.sharey(first)
                log_axes(ax)
                if r == 0:
                    ax.set_title(name, fontsize=10, fontweight="bold")
                if r == len(groups) - 1:
                    ax.set_xlabel(xlabel, fontsize=8.5)
                else:
                    ax.tick_params(labelbottom=False)
                if column == 0:
                    ax.set_ylabel(ylabel, fontsize=8.5)
    return figure, panels, blocks


def family_legends(panels, blocks, groups, peers: list[str]) -> None:
    """Each family's methods, right of the last panel of its row in every block."""
    for block in blocks:
        for key, label, methods in groups:
            handles = [Line2D([], [], linewidth=1.4, markersize=4.5, linestyle="--" if key == PEERS[0] else "-",
                              **method_style(m, peers)) for m in methods]
            panels[(block[-1], key)].legend(handles, methods, title=label, loc="upper left",
                                            bbox_to_anchor=(1.03, 1.0), borderaxespad=0, fontsize=7.5,
                                            title_fontsize=8, frameon=False, alignment="left")


def _setting(p: Point) -> str:
    if p.order:
        return f"order {p.order}, h = {p.h:g} s"
    return f"h = {p.h:g} s" if math.isfinite(p.h) else f"tol = {p.tol:g}"


COSTS = {"evaluations": ("cost [evaluations]", "work-precision", "evaluations (right-hand sides + Jacobian columns)"),
         "seconds": ("run time [s]", "work-precision-time", "run time (median of repeats)")}
# what the error axis measures: the Point's field, its reference's estimate, the axis, the charts' stem
# suffix, the unit, and the title's words
MEASURES = {"error": ("reference_error", "error [m]", "", "m", "the traced point's largest position error"),
            "event_error": ("reference_event_error", "event time error [s]", "-events", "s",
                            "the largest error of an event's time")}


def chart_stem(cost: str, measure: str) -> str:
    """work-precision, work-precision-time, work-precision-events, work-precision-events-time."""
    return "work-precision" + MEASURES[measure][2] + ("-time" if cost == "seconds" else "")


def work_precision_figure(points: list[Point], cost: str, measure: str = "error"):
    """Error against one cost, a panel per object and family; the object's Pareto front (all methods)
    as a black staircase with its points circled in each of its panels. `measure`: the position error or,
    for objects with events, the error of the events' times."""
    xlabel, _, what = COSTS[cost]
    floor_field, ylabel, _, unit, title = MEASURES[measure]
    stem = chart_stem(cost, measure)
    error = (lambda p: getattr(p, measure))  # noqa: E731
    points = [p for p in points if not math.isnan(error(p))]
    objects = list(dict.fromkeys(p.object for p in points))
    groups = method_families(p.method for p in points)
    peers = [m for m in dict.fromkeys(p.method for p in points) if m not in METHOD]
    figure, panels, blocks = family_grid(objects, groups, xlabel, ylabel)
    tips = Tooltips(stem)
    for name in objects:
        mine = [p for p in points if p.object == name and math.isfinite(error(p)) and error(p) > 0]
        series = {m: sorted((p for p in mine if p.method == m), key=lambda p: getattr(p, cost))
                  for m in dict.fromkeys(p.method for p in mine)}
        front = pareto_front(mine, cost, measure)
        floor = max((getattr(p, floor_field) for p in mine), default=math.nan)
        for key, _, methods in groups:
            ax = panels[(name, key)]
            for method, line in series.items():
                if method not in methods:
                    ax.plot([getattr(p, cost) for p in line], [error(p) for p in line], color=CONTEXT,
                            linewidth=0.8, zorder=1)
            if floor > 0:  # errors below the reference's own are not resolved
                ax.axhspan(floor * 1e-3, floor, color=BAND, zorder=0)
            ax.step([getattr(p, cost) for p in front], [error(p) for p in front], where="post", color="black",
                    linewidth=1.1, zorder=3)
            ax.scatter([getattr(p, cost) for p in front], [error(p) for p in front], s=40, facecolors="none",
                       edgecolors="black", linewidths=1.0, zorder=4, gid=f"{stem}-front-{name}-{key}")
            for method in methods:
                line = series.get(method, [])
                style = method_style(method, peers)
                ax.plot([getattr(p, cost) for p in line], [error(p) for p in line], color=style["color"],
                        linewidth=1.4, linestyle="--" if key == PEERS[0] else "-", zorder=5)
                for p in line:
                    on_front = " (on the Pareto front)" if p in front else ""
                    tips.point(ax, getattr(p, cost), error(p),
                               f"{name}: {method}, {_setting(p)}: error {error(p):.2g} {unit}, {p.evaluations} "
                               f"evaluations, {p.seconds * 1e3:.3g} ms{on_front}", markersize=4, zorder=6, **style)
    family_legends(panels, blocks, groups, peers)
    figure.legend([Line2D([], [], color="black", marker="o", markerfacecolor="none", linewidth=1.1),
                   Line2D([], [], color=CONTEXT, linewidth=0.8), Patch(color=BAND)],
                  ["Pareto front of all methods (circled points)", "the other families' methods",
                   "below the reference's own error"], loc="outside lower center", ncol=3, fontsize=8, frameon=False)
    figure.suptitle(f"Work-precision: {title} over {STOP:g} s (outputs every {STEP:g} s)\nagainst {what}",
                    fontsize=10)
    return figure, tips


def work_precision_chart(points: list[Point], out: Path) -> list[Path]:
    """work-precision (error against evaluations) and work-precision-time (against seconds); where objects
    have events, work-precision-events and work-precision-events-time (their times' error) as well."""
    paths = []
    for measure in MEASURES:
        if measure != "error" and all(math.isnan(getattr(p, measure)) for p in points):
            continue
        for cost in COSTS:
            figure, tips = work_precision_figure(points, cost, measure)
            paths += save(figure, out, chart_stem(cost, measure), tips)
    return paths


def _stability_order(methods) -> list[str]:
    return [m for _, _, group in method_families(methods) for m in group]


def _case_label(object_name: str, damping: float, release: float) -> str:
    return f"{object_name}, d = {damping:.3g}/s" + (f", released at {release:g} rad" if release > 1 else "")


def stability_figures(limits, cases, tables: dict):
    """Each method's region |growth| <= 1 in the complex h*lambda plane with the measured limits on
    it (filled) and the predicted ones (hollow); and the limits per case side by side."""
    import numpy as np

    from harness.studies.stability import growth_on_grid, measured_point
    by_key = {(c.object, round(c.damping, 12), c.release): c for c in cases}
    methods = _stability_order(limit.method for limit in limits)
    columns = 4
    rows = math.ceil((len(methods) + 1) / columns)  # one more panel for the legend
    figure = plt.figure(figsize=(WIDTH, 0.7 + 2.45 * rows), layout="constrained")
    axes = figure.subplots(rows, columns, squeeze=False)
    shapes = "osD^v<>ph*"  # one marker shape per object, in the order the cases come
    markers = {name: shapes[k % len(shapes)] for k, name in enumerate(dict.fromkeys(c.object for c in cases))}
    tips = Tooltips("stability-regions")
    for ax, method in zip(axes.flat, methods):
        mine = [(limit, by_key[(limit.object, round(limit.damping, 12), limit.release)]) for limit in limits
                if limit.method == method]
        points = [(limit, case, measured_point(limit, case)) for limit, case in mine]
        table = tables[method]
        # The window: the measured linear limits. Not those of an A-stable method (one step per 100
        # periods, far out on the half-plane it fills), nor Stormer-Verlet's overdamped ones (its
        # region is drawn for an oscillator's pair z, conj(z), which a real pair is not).
        shown = [z for limit, case, z in points if case.linear and math.isfinite(limit.theory_limit)
                 and not (table.get("partitioned") and z.imag == 0)]
        reach = max((abs(z) for z in shown), default=4.0)
        x = np.linspace(-1.35 * reach, 0.45 * reach, 200)
        y = np.linspace(-1.25 * reach, 1.25 * reach, 200)
        grid = x[None, :] + 1j * y[:, None]
        g = growth_on_grid(table, grid)
        ax.contourf(x, y, (g <= 1.0).astype(float), levels=[0.5, 1.5], colors=["#cfe3f7"])
        ax.contour(x, y, g, levels=[1.0], colors=["#2b6cb0"], linewidths=1.0)
        ax.axhline(0, color="grey", linewidth=0.5)
        ax.axvline(0, color="grey", linewidth=0.5)
        def inside(w: complex) -> bool:  # a point outside the window is not drawn (nor hovered)
            return x[0] <= w.real <= x[-1] and y[0] <= w.imag <= y[-1]
        for limit, case, z in points:
            label = _case_label(limit.object, limit.damping, limit.release)
            if case.linear:
                predicted = (f", predicted {limit.theory_limit:.3g}" if math.isfinite(limit.theory_limit)
                             else ", predicted unbounded")
                text = f"{method}, {label}: stable up to h·ω = {limit.measured_limit:.3g}{predicted}"
                t = z * limit.theory_limit / limit.measured_limit if math.isfinite(limit.theory_limit) else None
                if t is not None and inside(t):
                    tips.point(ax, t.real, t.imag, text, marker=markers[case.object], markerfacecolor="none",
                               color="black", markersize=8)
                # above the predicted ring, which nearly coincides: the measured point stays hoverable
                if inside(z):
                    tips.point(ax, z.real, z.imag, text, marker=markers[case.object], color="#c53030",
                               markersize=4.5, zorder=5)
            elif inside(z):
                tips.point(ax, z.real, z.imag, f"{method}, {label} (nonlinear): stable up to h·ω = "
                           f"{limit.measured_limit:.3g}", marker="x", color="#805ad5", markersize=7, zorder=5)
        ax.set_title(method if shown else f"{method}: A-stable", fontsize=9)
        ax.set_xlim(x[0], x[-1])
        ax.set_ylim(y[0], y[-1])
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
        ax.set_xlabel("Re h·λ [1]", fontsize=7.5, labelpad=1)
        ax.set_ylabel("Im h·λ [1]", fontsize=7.5, labelpad=1)
    for ax in list(axes.flat)[len(methods):]:
        ax.axis("off")
    handles = [Line2D([], [], linestyle="none", marker=marker, color="#c53030") for marker in markers.values()]
    labels = [f"measured: {name}" for name in markers]
    handles += [Line2D([], [], linestyle="none", marker="o", markerfacecolor="none", color="black"),
                Line2D([], [], linestyle="none", marker="x", color="#805ad5"), Patch(color="#cfe3f7")]
    labels += ["predicted over the same window", "measured: 3 rad release (nonlinear)", "|growth| <= 1"]
    list(axes.flat)[-1].legend(handles, labels, loc="center", fontsize=7.5, frameon=False)
    figure.suptitle("Stability regions with the limits measured on the FMUs (100 periods, energy <= 1.5 x start; "
                    "A-stable: stable up to one step per 100 periods)", fontsize=9.5)
    regions = (figure, tips)

    groups = list(dict.fromkeys((limit.object, limit.damping, limit.release) for limit in limits))
    omega = {key: case.omega for key, case in by_key.items()}
    figure, ax = plt.subplots(figsize=(WIDTH, 4.6), layout="constrained")
    tips = Tooltips("stability-limits")
    # a colour per damping ratio, evenly spread: the ratios crowd near 0 (0, 0.1, ..., 0.95, 2, 10)
    levels = sorted({round(d / (2 * omega[(o, round(d, 12), r)]), 12) for o, d, r in groups if r <= 1}) or [0.0]
    colours = matplotlib.colors.ListedColormap(plt.get_cmap("viridis")([0.92 * k / max(len(levels) - 1, 1)
                                                                        for k in range(len(levels))]))
    ratios = matplotlib.colors.BoundaryNorm([k - 0.5 for k in range(len(levels) + 1)], len(levels))
    for k, group in enumerate(groups):
        object_name, damping, release = group
        mine = [limit for limit in limits if (limit.object, limit.damping, limit.release) == group]
        ratio = damping / (2 * omega[(object_name, round(damping, 12), release)])
        nonlinear = release > 1
        for limit in mine:
            x = methods.index(limit.method) + (k - len(groups) / 2) * 0.045
            predicted = f", predicted {limit.theory_limit:.3g}" if math.isfinite(limit.theory_limit) else ""
            style = ({"marker": "x", "color": "#805ad5", "markersize": 5} if nonlinear else
                     {"marker": markers[object_name], "color": colours(levels.index(round(ratio, 12))),
                      "markersize": 4.5})
            # the measured marker above the predicted dash (which is wider, so it shows on both sides)
            tips.point(ax, x, limit.measured_limit, f"{limit.method}, {_case_label(*group)}: measured "
                       f"{limit.measured_limit:.3g}{predicted}", zorder=3, **style)
            if math.isfinite(limit.theory_limit):
                ax.plot(x, limit.theory_limit, "_", color="black", markersize=7, zorder=2.5)
    ax.set_xticks(range(len(methods)), methods, rotation=55, ha="right", rotation_mode="anchor", fontsize=8)
    ax.set_xlim(-0.7, len(methods) - 0.3)
    ax.set_yscale("log")
    ax.set_ylabel("largest stable h·ω [rad per step]", fontsize=8.5)
    ax.tick_params(axis="y", labelsize=7.5)
    ax.grid(True, axis="y", alpha=0.3)
    handles = [Line2D([], [], linestyle="none", marker=markers[name], color="grey") for name in markers]
    labels = [f"measured: {name}" for name in markers]
    handles += [Line2D([], [], linestyle="none", marker="x", color="#805ad5"),
                Line2D([], [], linestyle="none", marker="_", color="black", markersize=8)]
    labels += ["measured: 3 rad release", "predicted"]
    ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0, fontsize=7.5,
              frameon=False)
    bar = figure.colorbar(plt.cm.ScalarMappable(norm=ratios, cmap=colours), ax=ax, location="bottom", shrink=0.5,
                          aspect=35, pad=0.02, ticks=range(len(levels)))
    bar.ax.set_xticklabels([f"{level:g}" for level in levels])
    bar.set_label("damping ratio d / (2 ω) of the linear cases [1]", fontsize=8)
    bar.ax.tick_params(labelsize=7.5)
    ax.set_title("Stability limits per method and case (A-stable methods: stable at every step tried, up to 628)",
                 fontsize=9.5)
    return [(regions[0], "stability-regions", regions[1]), (figure, "stability-limits", tips)]


def stability_charts(limits, cases, tables: dict, out: Path) -> list[Path]:
    return [path for figure, stem, tips in stability_figures(limits, cases, tables)
            for path in save(figure, out, stem, tips)]


COUPLING_MARKERS = "osDv^P"


def coupling_figure(points, scene: str = "Coupled pendulums"):
    """Coupling error against the communication step, against fmi2DoStep calls and against seconds.
    (The CSV also has the right-hand-side evaluations: with the scene's fixed internal step they
    change only with the passes a step takes, not with H.)"""
    configurations = list(dict.fromkeys(p.configuration for p in points))
    if not any(math.isfinite(p.error) and p.error > 0 for p in points):
        raise HarnessError("coupling: every run stopped before its end (no finite error to chart); "
                           "see the CSV for where")
    figure, axes = plt.subplots(1, 3, figsize=(WIDTH, 3.9), sharey=True, layout="constrained")
    tips = Tooltips("coupling")
    costs = (("step", "communication step H [s]"), ("do_steps", "cost [fmi2DoStep calls, all components]"),
             ("seconds", "run time [s], median of repeats"))
    for k, name in enumerate(configurations):
        mine = sorted((p for p in points if p.configuration == name and math.isfinite(p.error) and p.error > 0),
                      key=lambda p: p.step)
        # iterated runs land on the same errors: hollow markers keep both visible
        style = dict(color=COLOURS[k % len(COLOURS)], marker=COUPLING_MARKERS[k % len(COUPLING_MARKERS)],
                     markersize=6 if "iterated" in name else 4.5,
                     markerfacecolor="none" if "iterated" in name else COLOURS[k % len(COLOURS)])
        for ax, (field, _) in zip(axes, costs):
            ax.plot([getattr(p, field) for p in mine], [p.error for p in mine], color=style["color"],
                    linestyle="--" if "iterated" in name else "-", linewidth=1.3)
            for p in mine:
                tips.point(ax, getattr(p, field), p.error, f"{name}, H = {p.step:g} s: error {p.error:.2g} m, "
                           f"{p.do_steps} fmi2DoStep calls, {p.seconds * 1e3:.3g} ms", **style)
    steps = sorted({p.step for p in points})
    for order, anchor, dash in ((1, 0.5, ":"), (2, 0.01, "-.")):
        axes[0].plot(steps, [anchor * (h / steps[-1]) ** order for h in steps], color="grey", linewidth=0.9,
                     linestyle=dash)
    for ax, (_, label) in zip(axes, costs):
        log_axes(ax)
        ax.set_xlabel(label, fontsize=8.5)
    axes[0].set_xticks(steps, [f"{h:g}" for h in steps])  # the steps measured: one log decade holds them all
    axes[0].set_ylabel("largest bob position error [m]", fontsize=8.5)
    handles = [Line2D([], [], color=COLOURS[k % len(COLOURS)], marker=COUPLING_MARKERS[k % len(COUPLING_MARKERS)],
                      markerfacecolor="none" if "iterated" in name else COLOURS[k % len(COLOURS)],
                      linestyle="--" if "iterated" in name else "-") for k, name in enumerate(configurations)]
    handles += [Line2D([], [], color="grey", linestyle=":"), Line2D([], [], color="grey", linestyle="-.")]
    figure.legend(handles, [*configurations, "slope 1", "slope 2"], loc="outside lower center", ncol=4, fontsize=8,
                  frameon=False)
    figure.suptitle(f"{scene}: master configurations against a monolithic reference", fontsize=10)
    return figure, tips


def _scene_chart(figure_of, points, out: Path, stem: str, scene: str) -> list[Path]:
    """A scene's chart saved as `stem`; what cannot be drawn names the CSV it came from."""
    try:
        figure, tips = figure_of(points, scene)
    except HarnessError as error:
        raise HarnessError(f"{out / (stem + '.csv')}: {error}") from None
    return save(figure, out, stem, tips)


def coupling_chart(points, out: Path, scene: str = "Coupled pendulums") -> list[Path]:
    return _scene_chart(coupling_figure, points, out, "coupling", scene)


def contact_figure(points, scene: str = "Newton's cradle of 5 FMUs"):
    """The masters on a contact scene: the error of the outgoing velocities against macro steps and against
    seconds, and the energy created per contact onset against macro steps."""
    masters = list(dict.fromkeys(p.master for p in points))
    finite = [p for p in points if math.isfinite(p.error) and p.error > 0]
    if not finite:
        raise HarnessError("contacts: every run stopped before its end (no finite error to chart); see the CSV")
    figure, axes = plt.subplots(1, 3, figsize=(WIDTH, 3.9), layout="constrained")
    tips = Tooltips("contacts")
    panels = ((axes[0], "macro_steps", "error", "macro steps"),
              (axes[1], "seconds", "error", "run time [s], median of repeats"),
              (axes[2], "macro_steps", "per_onset", "macro steps"))
    for k, name in enumerate(masters):
        mine = sorted((p for p in finite if p.master == name), key=lambda p: p.macro_steps)
        style = dict(color=COLOURS[k % len(COLOURS)], marker=COUPLING_MARKERS[k % len(COUPLING_MARKERS)],
                     markersize=4.5)
        for ax, x, y, _ in panels:
            values = [(getattr(p, x), abs(getattr(p, y))) for p in mine if abs(getattr(p, y)) > 0]
            ax.plot([v[0] for v in values], [v[1] for v in values], color=style["color"], linewidth=1.3)
            for p in mine:
                if abs(getattr(p, y)) > 0:
                    tips.point(ax, getattr(p, x), abs(getattr(p, y)),
                               f"{name}, {p.setting}: {p.macro_steps} macro steps, velocity error {p.error:.2g}, "
                               f"energy created {p.energy:.2g} ({p.per_onset:.2g} per onset), {p.seconds:.3g} s",
                               **style)
    for ax, _, y, label in panels:
        log_axes(ax)
        ax.set_xlabel(label, fontsize=8.5)
    axes[0].set_ylabel("error of the outgoing velocities (relative)", fontsize=8.5)
    axes[2].set_ylabel("|energy created| per contact onset (relative)", fontsize=8.5)
    handles = [Line2D([], [], color=COLOURS[k % len(COLOURS)], marker=COUPLING_MARKERS[k % len(COUPLING_MARKERS)])
               for k in range(len(masters))]
    figure.legend(handles, masters, loc="outside lower center", ncol=3, fontsize=8, frameon=False)
    figure.suptitle(f"{scene}: masters against a monolithic reference with its contacts located as events", fontsize=10)
    return figure, tips


def contact_chart(points, out: Path, scene: str = "Newton's cradle of 5 FMUs") -> list[Path]:
    return _scene_chart(contact_figure, points, out, "contacts", scene)


LONG_RUN_ERRORS = (1e-9, 1e4)  # the y range: symmetric methods' bands to blown-up runs


def long_run_figure(series):
    """Energy error against time over the long run, log-log, a panel per case and family."""
    objects = list(dict.fromkeys(s.object for s in series))
    groups = method_families(s.method for s in series)
    figure, panels, blocks = family_grid(objects, groups, "time [periods]", "energy error [1]", panel_height=1.45)
    tips = Tooltips("long-run")
    for name in objects:
        curves = {}
        for s in (s for s in series if s.object == name):
            points = [(t, e) for t, e in zip(s.times, s.errors) if t > 0 and e > 0 and math.isfinite(e)]
            if points:
                curves[s.method] = (s, points)
        for key, _, methods in groups:
            ax = panels[(name, key)]
            for method, (s, points) in curves.items():
                if method not in methods:
                    ax.plot(*zip(*points), color=CONTEXT, linewidth=0.8, zorder=1)
            for method in methods:
                if method not in curves:
                    continue
                s, points = curves[method]
                style = method_style(method)
                setting = f"h = {s.h:.4g} s" if math.isfinite(s.h) else f"tol = {s.tol:g}"
                text = (f"{name}: {method}, {setting}, {s.cost_per_period:.0f} evaluations per period: slope "
                        f"{s.slope:.2f}, {points[-1][1]:.2g} after {points[-1][0]:,.0f} periods")
                tips.attach(ax.plot(*zip(*points), color=style["color"], linewidth=1.4, zorder=5)[0], text, "curve")
                if LONG_RUN_ERRORS[0] <= points[-1][1] <= LONG_RUN_ERRORS[1]:  # a run that blew up ends off the chart
                    tips.point(ax, *points[-1], text, markersize=4, zorder=6, **style)
            ax.set_ylim(*LONG_RUN_ERRORS)
    family_legends(panels, blocks, groups, [])
    figure.legend([Line2D([], [], color=CONTEXT, linewidth=0.8)], ["the other families' methods"],
                  loc="outside lower center", fontsize=8, frameon=False)
    cost = statistics.median(s.cost_per_period for s in series) if series else 0
    figure.suptitle(f"Energy error over a long run: the largest |E(t) - E(0)| so far over the swing's energy, "
                    f"every method at about {cost:.0f} evaluations per period", fontsize=10)
    return figure, tips


def long_run_chart(series, out: Path) -> list[Path]:
    figure, tips = long_run_figure(series)
    return save(figure, out, "long-run", tips)


def redraw(folder: Path) -> list[Path]:
    """Every chart whose CSV is in `folder` drawn again from it; the sweeps are not run, so the
    measured errors and seconds stay as they are. The stability chart takes its cases (eigenvalues
    and frequencies, computed, not measured) from the built FMUs."""
    from harness.studies import coupling, long_run, stability, work_precision
    folder = Path(folder)
    written_paths = []
    if (folder / "work-precision.csv").is_file():
        written_paths += work_precision_chart(work_precision.read_csv(folder / "work-precision.csv"), folder)
    if (folder / "long-run.csv").is_file():
        written_paths += long_run_chart(long_run.series_from_rows(long_run.read_csv(folder / "long-run.csv")),
                                        folder)
    if (folder / "coupling.csv").is_file():
        written_paths += coupling_chart(coupling.read_csv(folder / "coupling.csv"), folder)
    if (folder / "contacts.csv").is_file():
        from harness.studies import contact_study
        written_paths += contact_chart(contact_study.read_csv(folder / "contacts.csv"), folder)
    if (folder / "stability.csv").is_file():
        from harness.fmi.fmus import build_dir, build_fmus
        limits = stability.read_csv(folder / "stability.csv")
        objects = list(dict.fromkeys(limit.object for limit in limits))
        if not all((build_dir() / "fmus" / f"{name}.fmu").is_file() for name in objects):
            build_fmus()  # the cases read the FMUs' parameters and object files, which any build has
        keys = {(limit.object, round(limit.damping, 12), limit.release) for limit in limits}
        every = stability.cases(build_dir() / "fmus", full=True, objects=objects)
        chosen = [c for c in every if (c.object, round(c.damping, 12), c.release) in keys]
        written_paths += stability_charts(limits, chosen, stability.atlas_tables(), folder)
    if not written_paths:
        raise HarnessError(f"{folder}: no work-precision.csv, long-run.csv, coupling.csv, contacts.csv or "
                           "stability.csv to draw")
    return written_paths


if __name__ == "__main__":
    for argument in sys.argv[1:] or ["docs/charts"]:
        print("wrote " + ", ".join(str(path) for path in redraw(Path(argument))))
