"""Trace pictures: the paths of the moving masses, as in the thesis's trace mode (figures C.1-C.3)."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)

from harness.fmi.simulation import SimulationResult  # noqa: E402
from harness.output import write_figure  # noqa: E402


def draw_traces(panels: list[tuple[str, SimulationResult, list[tuple[str, str]], tuple[float, float]]],
                path: str | Path) -> None:
    """One panel per (title, result, [(x column, y column), ...], anchor)."""
    figure, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.4), squeeze=False)
    for ax, (title, result, pairs, anchor) in zip(axes[0], panels):
        for x_name, y_name in pairs:
            ax.plot(result[x_name], result[y_name], lw=0.6, label=f"({x_name}, {y_name})")
            ax.plot(result[x_name][-1], result[y_name][-1], "o", ms=5)
        ax.plot(*anchor, "k^", ms=7)
        ax.set_title(title, fontsize=9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        if getattr(result, "discarded_at", None) is not None:
            ax.text(0.02, 0.02, f"stopped: discard at t = {result.discarded_at:.3f} s", transform=ax.transAxes,
                    color="red", fontsize=8)
    figure.tight_layout()
    write_figure(figure, Path(path))
    plt.close(figure)
