"""Charts of the sweeps (matplotlib, written as PNG and SVG)."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from harness.work_precision import Point, pareto_front  # noqa: E402

PEER_STYLE = {"scipy-RK45": "s", "scipy-DOP853": "D", "scipy-LSODA": "^", "fmpy-CVode": "v"}


def save(figure, out: Path, stem: str) -> list[Path]:
    paths = [out / f"{stem}.png", out / f"{stem}.svg"]
    for path in paths:
        figure.savefig(path, dpi=110)
    plt.close(figure)
    return paths


def work_precision_chart(points: list[Point], out: Path) -> list[Path]:
    """Error against cost (top: right-hand-side evaluations, bottom: seconds) per object; the Pareto
    front of each panel drawn as a black staircase through its points."""
    objects = list(dict.fromkeys(p.object for p in points))
    methods = list(dict.fromkeys(p.method for p in points))
    colours = plt.get_cmap("tab20")
    figure, axes = plt.subplots(2, len(objects), figsize=(6 * len(objects), 10), squeeze=False)
    for column, name in enumerate(objects):
        mine = [p for p in points if p.object == name and math.isfinite(p.error) and p.error > 0]
        for row, cost in enumerate(("rhs_evals", "seconds")):
            ax = axes[row][column]
            for k, method in enumerate(methods):
                series = sorted((p for p in mine if p.method == method), key=lambda p: getattr(p, cost))
                if not series:
                    continue
                peer = method in PEER_STYLE
                ax.plot([getattr(p, cost) for p in series], [p.error for p in series],
                        marker=PEER_STYLE.get(method, "o"), linestyle="--" if peer else "-", markersize=4,
                        color="black" if method == "fmpy-CVode" else colours(k % 20), label=method,
                        alpha=0.9 if peer else 0.8)
            front = pareto_front(mine, cost)
            ax.step([getattr(p, cost) for p in front], [p.error for p in front], where="post", color="black",
                    linewidth=2.2, alpha=0.35, label="Pareto front")
            ax.scatter([getattr(p, cost) for p in front], [p.error for p in front], s=70, facecolors="none",
                       edgecolors="black", linewidths=1.2, zorder=5)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.grid(True, which="major", alpha=0.3)
            ax.set_xlabel("right-hand-side evaluations" if cost == "rhs_evals" else "seconds (median of repeats)")
            ax.set_ylabel("largest position error of the outer mass [m]")
            ax.set_title(f"{name}: error against {'evaluations' if cost == 'rhs_evals' else 'time'}")
    axes[0][-1].legend(fontsize=7, ncol=2, loc="lower left")
    figure.suptitle("Work-precision, 10 s from the default start, communication step 0.01 s")
    figure.tight_layout()
    return save(figure, out, "work-precision")
