"""Charts of the sweeps (matplotlib, written as PNG and SVG)."""
from __future__ import annotations

import math
import statistics
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from harness.errors import HarnessError  # noqa: E402
from harness.output import write_figure  # noqa: E402
from harness.studies.work_precision import Point, pareto_front  # noqa: E402

PEER_STYLE = {"scipy-RK45": "s", "scipy-DOP853": "D", "scipy-LSODA": "^", "fmpy-CVode": "v"}


METHOD_PALETTE = plt.get_cmap("tab20").colors + plt.get_cmap("tab20b").colors  # 40: a colour per method


def save(figure, out: Path, stem: str) -> list[Path]:
    paths = [out / f"{stem}.png", out / f"{stem}.svg"]
    for path in paths:
        write_figure(figure, path)
    plt.close(figure)
    return paths


def work_precision_chart(points: list[Point], out: Path) -> list[Path]:
    """Error against cost (top: evaluations, the implicit methods' Jacobian columns included; bottom:
    seconds) per object; the Pareto front of each panel drawn as a black staircase through its points."""
    objects = list(dict.fromkeys(p.object for p in points))
    methods = list(dict.fromkeys(p.method for p in points))
    figure, axes = plt.subplots(2, len(objects), figsize=(6 * len(objects), 10), squeeze=False)
    for column, name in enumerate(objects):
        mine = [p for p in points if p.object == name and math.isfinite(p.error) and p.error > 0]
        for row, cost in enumerate(("evaluations", "seconds")):
            ax = axes[row][column]
            for k, method in enumerate(methods):
                series = sorted((p for p in mine if p.method == method), key=lambda p: getattr(p, cost))
                if not series:
                    continue
                peer = method in PEER_STYLE
                ax.plot([getattr(p, cost) for p in series], [p.error for p in series],
                        marker=PEER_STYLE.get(method, "o"), linestyle="--" if peer else "-", markersize=4,
                        color="black" if method == "fmpy-CVode" else METHOD_PALETTE[k % len(METHOD_PALETTE)],
                        label=method,
                        alpha=0.9 if peer else 0.8)
            front = pareto_front(mine, cost)
            ax.step([getattr(p, cost) for p in front], [p.error for p in front], where="post", color="black",
                    linewidth=2.2, alpha=0.35, label="Pareto front")
            ax.scatter([getattr(p, cost) for p in front], [p.error for p in front], s=70, facecolors="none",
                       edgecolors="black", linewidths=1.2, zorder=5)
            floor = max((p.reference_error for p in mine), default=math.nan)
            if floor > 0:  # errors below the reference's own are not resolved
                ax.axhspan(floor * 1e-3, floor, color="grey", alpha=0.15, label="below the reference's error")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.grid(True, which="major", alpha=0.3)
            ax.set_xlabel("evaluations (right-hand sides + Jacobian columns)" if cost == "evaluations"
                          else "seconds (median of repeats)")
            ax.set_ylabel("largest position error of the traced point [m]")
            ax.set_title(f"{name}: error against {'evaluations' if cost == 'evaluations' else 'time'}")
    labelled = {}  # every method once, also one only some objects have (stormer_verlet)
    for ax in axes[0]:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            labelled.setdefault(label, handle)
    axes[0][-1].legend(list(labelled.values()), list(labelled), fontsize=7, ncol=2, loc="lower left")
    figure.suptitle("Work-precision, 10 s from the default start, communication step 0.01 s")
    figure.tight_layout()
    return save(figure, out, "work-precision")


def stability_charts(limits, cases, tables: dict, out: Path) -> list[Path]:
    """Each method's region |growth| <= 1 in the complex h*lambda plane with the measured limits on
    it (filled) and the predicted ones (hollow); and the limits per case side by side."""
    import numpy as np

    from harness.studies.stability import growth_on_grid, measured_point
    by_key = {(c.object, round(c.damping, 12), c.release): c for c in cases}
    methods = list(dict.fromkeys(limit.method for limit in limits))
    columns = 4
    rows = math.ceil(len(methods) / columns)
    figure, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 4 * rows), squeeze=False)
    shapes = "osD^v<>ph*"  # one marker shape per object, in the order the cases come
    markers = {name: shapes[k % len(shapes)] for k, name in enumerate(dict.fromkeys(c.object for c in cases))}
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
        x = np.linspace(-1.35 * reach, 0.45 * reach, 320)
        y = np.linspace(-1.25 * reach, 1.25 * reach, 320)
        grid = x[None, :] + 1j * y[:, None]
        g = growth_on_grid(table, grid)
        ax.contourf(x, y, (g <= 1.0).astype(float), levels=[0.5, 1.5], colors=["#cfe3f7"])
        ax.contour(x, y, g, levels=[1.0], colors=["#2b6cb0"], linewidths=1.0)
        ax.axhline(0, color="grey", linewidth=0.5)
        ax.axvline(0, color="grey", linewidth=0.5)
        for limit, case, z in points:
            if case.linear:
                ax.plot(z.real, z.imag, markers[case.object], color="#c53030", markersize=5)
                if math.isfinite(limit.theory_limit):
                    t = z * limit.theory_limit / limit.measured_limit
                    ax.plot(t.real, t.imag, markers[case.object], markerfacecolor="none", color="black", markersize=9)
            else:
                ax.plot(z.real, z.imag, "x", color="#805ad5", markersize=8)
        ax.set_title(method if shown else f"{method} (A-stable: measured stable up to one step per window)",
                     fontsize=10 if shown else 8)
        ax.set_xlim(x[0], x[-1])
        ax.set_ylim(y[0], y[-1])
        ax.set_aspect("equal")
        ax.set_xlabel("Re h·λ")
        ax.set_ylabel("Im h·λ")
    for ax in list(axes.flat)[len(methods):]:
        ax.axis("off")
    legend_ax = list(axes.flat)[-1]
    for name, marker in markers.items():
        legend_ax.plot([], [], marker, color="#c53030", label=f"measured: {name}")
    legend_ax.plot([], [], "o", markerfacecolor="none", color="black", label="predicted over the same window")
    legend_ax.plot([], [], "x", color="#805ad5", label="measured: 3 rad release (nonlinear)")
    legend_ax.fill_between([], [], color="#cfe3f7", label="|growth| <= 1")
    legend_ax.legend(loc="center", fontsize=9)
    figure.suptitle("Stability regions with the limits measured on the FMUs (100 periods, energy <= 1.5 x start)")
    figure.tight_layout()
    paths = save(figure, out, "stability-regions")

    groups = list(dict.fromkeys((limit.object, limit.damping, limit.release) for limit in limits))
    figure, ax = plt.subplots(figsize=(13, 6))
    colours = plt.get_cmap("viridis")
    for k, group in enumerate(groups):
        mine = {limit.method: limit for limit in limits if (limit.object, limit.damping, limit.release) == group}
        xs = [methods.index(m) + (k - len(groups) / 2) * 0.06 for m in mine]
        colour = colours(k / max(len(groups) - 1, 1))
        object_name, damping, release = group
        label = f"{object_name}, d = {damping:.3g}/s" + (", 3 rad" if release > 1 else "")
        ax.plot(xs, [limit.measured_limit for limit in mine.values()], markers[object_name], color=colour,
                markersize=5, linestyle="none", label=label)
        ax.plot(xs, [limit.theory_limit for limit in mine.values()], "_", color="black", markersize=9)
    ax.set_xticks(range(len(methods)), methods)
    ax.set_yscale("log")
    ax.set_ylabel("largest stable h·ω (measured: markers; predicted: black dashes)")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    ax.set_title("Stability limits per method and case")
    figure.tight_layout()
    return paths + save(figure, out, "stability-limits")


def coupling_chart(points, out: Path, scene: str = "Coupled pendulums") -> list[Path]:
    """Coupling error against the communication step, against fmi2DoStep calls and against seconds.
    (The CSV also has the right-hand-side evaluations: with the scene's fixed internal step they
    change only with the passes a step takes, not with H.)"""
    configurations = list(dict.fromkeys(p.configuration for p in points))
    if not any(math.isfinite(p.error) and p.error > 0 for p in points):
        raise HarnessError(f"{out / 'coupling.csv'}: every run stopped before its end (no finite error to chart); "
                           "see the CSV for where")
    figure, axes = plt.subplots(1, 3, figsize=(18, 5.5))
    colours = plt.get_cmap("tab10")
    for k, name in enumerate(configurations):
        mine = sorted((p for p in points if p.configuration == name and math.isfinite(p.error) and p.error > 0),
                      key=lambda p: p.step)
        style = dict(marker="o", color=colours(k), label=name, linestyle="--" if "iterated" in name else "-")
        axes[0].plot([p.step for p in mine], [p.error for p in mine], **style)
        axes[1].plot([p.do_steps for p in mine], [p.error for p in mine], **style)
        axes[2].plot([p.seconds for p in mine], [p.error for p in mine], **style)
    steps = sorted({p.step for p in points})
    for order, anchor in ((1, 0.5), (2, 0.01)):
        axes[0].plot(steps, [anchor * (h / steps[-1]) ** order for h in steps], color="grey", linewidth=0.8,
                     linestyle=":", label=f"slope {order}")
    for ax, label in zip(axes, ("communication step H [s]", "fmi2DoStep calls (all components)",
                                "seconds (median of repeats)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.grid(True, alpha=0.3)
        ax.set_xlabel(label)
        ax.set_ylabel("largest bob position error [m]")
    axes[0].legend(fontsize=8)
    figure.suptitle(f"{scene}: master configurations against a monolithic reference")
    figure.tight_layout()
    return save(figure, out, "coupling")


SYMMETRIC_COLOURS = {"implicit_midpoint": "#c53030", "gauss_legendre4": "#1a365d", "stormer_verlet": "black"}


def long_run_chart(series, out: Path) -> list[Path]:
    """Energy error against time over the long run, log-log, a panel per case; the symmetric methods
    drawn solid and thick, the others thin."""
    from harness.fmi.methods import METHOD
    objects = list(dict.fromkeys(s.object for s in series))
    methods = list(dict.fromkeys(s.method for s in series))
    figure, axes = plt.subplots(1, len(objects), figsize=(6.5 * len(objects), 6), squeeze=False)
    for ax, name in zip(axes[0], objects):
        for s in (s for s in series if s.object == name):
            points = [(t, e) for t, e in zip(s.times, s.errors) if t > 0 and e > 0 and math.isfinite(e)]
            if not points:
                continue
            symmetric = METHOD[s.method].symmetric if s.method in METHOD else False
            colour = (SYMMETRIC_COLOURS.get(s.method)
                      or METHOD_PALETTE[methods.index(s.method) % len(METHOD_PALETTE)])
            ax.plot(*zip(*points), color=colour, linewidth=2.4 if symmetric else 1.0,
                    linestyle="-" if symmetric else "--", label=f"{s.method} (slope {s.slope:.2f})")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(1e-9, 1e4)
        ax.grid(True, which="major", alpha=0.3)
        ax.set_xlabel("time [periods]")
        ax.set_ylabel("largest energy error so far / swing energy")
        ax.set_title(name)
        ax.legend(fontsize=6.5, ncol=2, loc="upper left")
    cost = statistics.median(s.cost_per_period for s in series) if series else 0
    figure.suptitle(f"Energy error over a long run, every method at about {cost:.0f} evaluations per period "
                    "(solid: symmetric methods)")
    figure.tight_layout()
    return save(figure, out, "long-run")
