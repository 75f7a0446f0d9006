"""What makes the charts readable, checked on the figures drawn from the committed CSV files (no
sweep runs): legends outside every data area, few coloured lines per panel, a unit on every axis
label, the Pareto front highlighted, and the SVG's tooltips (one per point, naming its method and
setting, nothing loaded from the network)."""
from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
from pathlib import Path

import matplotlib.colors
import pytest
from matplotlib.lines import Line2D

from harness.fmi.fmus import PROJECT_ROOT
from harness.fmi.methods import FAMILIES, METHODS
from harness.scene.report import Report, Section, interactive_chart, write_index
from harness.studies import coupling, long_run, work_precision
from harness.studies.charts import (COSTS, MOST_LINES, coupling_figure, long_run_figure, method_families, redraw,
                                    stability_figures, svg_of, work_precision_figure)
from harness.studies.stability import Case, Limit, theory_limit

CHARTS = PROJECT_ROOT / "docs" / "charts"
UNIT = re.compile(r"\[[^\]]+\]")


def figures():
    """(name, figure, tooltips, points with a tooltip) for every chart, from the committed CSV files."""
    drawn = []
    for folder in (CHARTS, CHARTS / "objects"):
        points = work_precision.read_csv(folder / "work-precision.csv")
        for cost in COSTS:
            figure, tips = work_precision_figure(points, cost)
            drawn.append((f"{folder.name} {cost}", figure, tips, points))
    series = long_run.series_from_rows(long_run.read_csv(CHARTS / "long-run.csv"))
    drawn.append(("long-run", *long_run_figure(series), series))
    points = coupling.read_csv(CHARTS / "coupling.csv")
    drawn.append(("coupling", *coupling_figure(points), points))
    for figure, stem, tips in stability_figures(*synthetic_atlas()):
        drawn.append((stem, figure, tips, None))
    for _, figure, _, _ in drawn:
        figure.canvas.draw()  # the layout places the legends
    return drawn


def synthetic_atlas():
    """A small atlas: explicit Runge-Kutta, Taylor and extrapolation tables, linear cases on the
    imaginary axis and a damping ray, and a nonlinear release; the measured limits 1% inside the
    predicted ones."""
    tables = {"euler": {"a": [[0.0]], "b": [1.0]},
              "rk4": {"a": [[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]],
                      "b": [1 / 6, 1 / 3, 1 / 3, 1 / 6]},
              "taylor": {"taylor": True, "order": 6}, "gbs": {"extrapolation": True, "columns": 3}}
    cases = [Case("SimplePendulum", 0.0, 0.01, 3.13, eigenvalues=(1j, -1j)),
             Case("SimplePendulum", 3.13, 0.01, 3.13, eigenvalues=(-0.5 + 0.75 ** 0.5 * 1j, -0.5 - 0.75 ** 0.5 * 1j)),
             Case("SimplePendulum", 0.0, 3.0, 3.13),
             Case("Chain3", 0.0, 0.01, 20.0, eigenvalues=(1j, -1j))]
    limits = []
    for method, table in tables.items():
        for case in cases:
            predicted = theory_limit(table, case)
            measured = 0.99 * predicted if case.linear else 1.5
            limits.append(Limit(case.object, method, case.damping, measured, predicted, case.release))
    return limits, cases, tables


@pytest.fixture(scope="module")
def drawn():
    return figures()


@pytest.fixture(scope="module")
def svgs(drawn):
    """Each chart's SVG with its tooltips, as the report embeds it: made once (half a minute) for the tests that
    read it and the one that loads it in a browser."""
    return {name: svg_of(figure, tips) for name, figure, tips, _ in drawn}


def visible_axes(figure):
    return [ax for ax in figure.axes if ax.axison]


def test_every_method_has_a_family_and_no_family_is_too_large():
    keys = {key for key, _ in FAMILIES}
    assert all(m.family in keys for m in METHODS)
    groups = method_families([m.name for m in METHODS] + ["scipy-RK45", "fmpy-CVode"])
    assert [key for key, _, _ in groups] == [*(key for key, _ in FAMILIES), "peers"]
    assert sorted(m for _, _, members in groups for m in members) == sorted(
        [m.name for m in METHODS] + ["scipy-RK45", "fmpy-CVode"])
    assert max(len(members) for _, _, members in groups) <= MOST_LINES


def test_no_legend_covers_data(drawn):
    for name, figure, _, _ in drawn:
        legends = [ax.get_legend() for ax in figure.axes if ax.get_legend()] + list(figure.legends)
        assert legends, name
        for legend in legends:
            box = legend.get_window_extent()
            for ax in visible_axes(figure):
                area = ax.get_window_extent()
                overlap = min(box.x1, area.x1) - max(box.x0, area.x0), min(box.y1, area.y1) - max(box.y0, area.y0)
                assert min(overlap) <= 1, (name, [t.get_text() for t in legend.get_texts()][:3], ax.get_title())


def coloured(line: Line2D) -> bool:
    r, g, b = matplotlib.colors.to_rgb(line.get_color())
    return max(r, g, b) - min(r, g, b) > 0.1  # the grey context and the black front are not


def test_few_coloured_lines_per_panel(drawn):
    for name, figure, _, _ in drawn:
        for ax in visible_axes(figure):
            lines = [line for line in ax.get_lines() if line.get_visible() and len(line.get_xdata()) > 1
                     and line.get_linestyle() not in ("None", "none", "") and coloured(line)]
            assert len(lines) <= MOST_LINES, (name, ax.get_title(), len(lines))


def test_every_axis_label_has_a_unit(drawn):
    for name, figure, _, _ in drawn:
        for ax in figure.axes:
            for label in (ax.get_xlabel(), ax.get_ylabel()):
                assert not label or UNIT.search(label), (name, label)
        for ax in visible_axes(figure):
            # values along x need a label; names along x (the methods of the stability limits) do not
            shown = [t.get_text() for t in ax.get_xticklabels() if t.get_visible() and t.get_text()]
            if any(re.fullmatch(r"[-−+0-9.e]+|\$.*\$", text) for text in shown):
                assert UNIT.search(ax.get_xlabel()), (name, ax.get_title())
            row = [other for other in visible_axes(figure)
                   if abs(other.get_position().y0 - ax.get_position().y0) < 1e-6]
            assert any(UNIT.search(other.get_ylabel()) for other in row) or ax.get_label() == "<colorbar>", \
                (name, ax.get_title())


def titles(svg: str) -> list[str]:
    return re.findall(r"<title>([^<]*)</title>", svg)


def test_every_point_has_a_tooltip_naming_method_and_setting(drawn, svgs):
    for name, figure, tips, points in drawn:
        svg = svgs[name]
        found = titles(svg)
        assert len(found) == len(tips.texts) > 0, name
        assert not re.search(r"(href|src)\s*=\s*[\"']https?:|url\(\s*[\"']?https?:|@import", svg), name
        # the namespaces are names, not addresses anyone loads: nothing else may name the web
        assert "http" not in re.sub(r'xmlns(:\w+)?="[^"]*"', "", svg), name
        if name.endswith(("evaluations", "seconds")):
            finite = [p for p in points if math.isfinite(p.error) and p.error > 0]
            assert len(found) == len(finite), name
            for p in finite:
                setting = f"order {p.order}, h = {p.h:g} s" if p.order else \
                    f"h = {p.h:g} s" if math.isfinite(p.h) else f"tol = {p.tol:g}"
                assert any(t.startswith(f"{p.object}: {p.method}, {setting}:") for t in found), (name, p)


def test_the_pareto_front_is_highlighted(drawn):
    for name, figure, tips, points in drawn:
        if not name.endswith(("evaluations", "seconds")):
            continue
        cost = name.split()[-1]
        for obj in dict.fromkeys(p.object for p in points):
            front = work_precision.pareto_front([p for p in points if p.object == obj and p.error > 0], cost)
            circled = [c for ax in figure.axes for c in ax.collections if (c.get_gid() or "").count(f"-front-{obj}-")]
            assert len(circled) == len(method_families(p.method for p in points)), (name, obj)
            for collection in circled:
                xy = sorted(map(tuple, collection.get_offsets().tolist()))
                assert xy == sorted((float(getattr(p, cost)), p.error) for p in front), (name, obj)
            on_front = [t for t in tips.texts.values() if t.startswith(f"{obj}:") and "Pareto front" in t]
            assert len(on_front) == len(front), (name, obj)


def test_redrawn_from_the_csv_files_keeping_them(tmp_path):
    for stem in ("coupling", "long-run"):
        shutil.copy(CHARTS / f"{stem}.csv", tmp_path)
    written = redraw(tmp_path)
    assert {p.name for p in written} == {"coupling.png", "coupling.svg", "long-run.png", "long-run.svg"}
    for stem in ("coupling", "long-run"):
        assert (tmp_path / f"{stem}.csv").read_bytes() == (CHARTS / f"{stem}.csv").read_bytes()
        assert (tmp_path / f"{stem}.png").stat().st_size > 10_000


def hover(url: str) -> dict:
    """What tests/browser/hover.mjs finds in Chromium: per document, its points and those whose centre
    shows no tooltip; and every request the page made."""
    node, chromium = shutil.which("node"), Path("/usr/bin/chromium")
    driver = PROJECT_ROOT / "tests" / "browser" / "hover.mjs"
    if node is None or not chromium.exists() or not (driver.parent / "node_modules" / "playwright-core").is_dir():
        pytest.skip("needs Node, Chromium and playwright-core in tests/browser (./run test installs them)")
    result = subprocess.run([node, str(driver), url], capture_output=True, text=True, timeout=120, check=True)
    return json.loads(result.stdout)


def test_the_report_shows_every_chart_with_a_tooltip_over_every_point(drawn, svgs, tmp_path):
    """Every chart's SVG embedded as the demo report embeds it, in Chromium: at each point's centre the
    browser finds an element with a tooltip (nothing without one drawn over it), and the page loads
    local files only."""
    stems = []
    for name, figure, tips, _ in drawn:
        stem = name.replace(" ", "-")
        (tmp_path / f"{stem}.svg").write_text(svgs[name])
        stems.append((stem, sum("-tip" in gid for gid in tips.texts)))
    page = write_index(Report([Section("Charts", "drawn", True,
                                       "".join(interactive_chart(stem, stem) for stem, _ in stems))]), tmp_path, 0.0)
    text = page.read_text()
    assert text.count('<object class="chart" data="') == len(stems) and "http" not in text
    assert '<object class="chart" data="coupling.svg" type="image/svg+xml"><img src="coupling.png"' in text
    seen = hover(page.as_uri())
    assert all(url.startswith("file://") for url in seen["requests"]), seen["requests"]
    frames = {f["url"].rsplit("/", 1)[-1]: f for f in seen["frames"]}
    for stem, points in stems:
        assert (frames[f"{stem}.svg"]["points"], frames[f"{stem}.svg"]["covered"][:3]) == (points, []), stem
