"""The main job, run as the README's quick start gives it (`./run demo`, with --out DIR): it writes
DIR/index.html with every section's verdict, the pictures it names, the animation, and the CSV files
behind the tables."""
from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest
from PIL import Image

from harness.view.wasm import WASI_LIBC

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def demo(fmu_paths, tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    result = subprocess.run(["./run", "demo", "--out", str(out)], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    return out, (out / "index.html").read_text()


def test_every_section_passes(demo):
    _, page = demo
    verdicts = re.findall(r"<li class='(pass|fail)'>", page)
    assert verdicts == ["pass"] * 5
    for title in ("Thesis scene", "Coupled pendulums", "Plan for the thesis scene", "Validation",
                  "Speed against accuracy"):
        assert f"<h2>{title}" in page


def test_every_picture_named_exists(demo):
    out, page = demo
    names = re.findall(r'<img src="([^"]+)"', page)
    assert {"thesis_scene_traces.png", "thesis_scene.gif", "coupled_traces.png", "work-precision.png",
            "stability-regions.png"} <= set(names)
    for name in names:
        assert (out / name).stat().st_size > 5_000, name


def test_the_report_links_the_live_view(demo):
    out, page = demo
    if shutil.which("clang") is None or not WASI_LIBC.exists():  # the report says why there is none
        assert "No live view" in page and "wasi-libc" in page
        return
    assert "<a href='live/index.html'>The scene live</a>" in page
    live = (out / "live" / "index.html").read_text()
    assert "thesis scene" in live and '"SimplePendulum"' in live  # the thesis scene's page, its modules inside


def test_the_animation_covers_the_scene(demo):
    """25 frames per second over the scene's 20 s."""
    with Image.open(demo[0] / "thesis_scene.gif") as gif:
        assert gif.n_frames == 501


def test_the_tables_have_their_data(demo):
    out, _ = demo
    for name in ("plan.csv", "work-precision.csv", "stability.csv", "coupled_pendulums.csv", "double.csv",
                 "spring_D34.csv", "spring_D104.csv", "simple.csv"):
        assert len((out / name).read_text().splitlines()) > 4, name


def test_the_plan_is_pointwise_where_the_motion_is_regular(demo):
    """The thesis scene's plan: the simple and spring pendulums part slowly (horizons far beyond the
    20 s) and are planned pointwise; the double pendulum parts within the scene and gets a plausible
    plan whose energy error is within its pixel's worth."""
    import csv
    with open(demo[0] / "plan.csv", newline="") as table:
        rows = {row["object"]: row for row in csv.DictReader(table)}
    for name in ("simple", "spring_D34", "spring_D104"):
        assert rows[name]["plan"] == "pointwise" and float(rows[name]["horizon"]) > 40, rows[name]
        assert float(rows[name]["verified_error"]) <= 0.004
    double = rows["double"]
    assert double["plan"] == "plausible" and float(double["horizon"]) < 20
    assert float(double["energy_error"]) <= float(double["energy_limit"])


def test_the_plan_covers_the_duration_asked_for(fmu_paths, tmp_path):
    """demo --duration plans the thesis scene over that time: the default's cost doubles with it."""
    import csv

    from harness.scene.report import plan_section

    def default_costs(duration: float) -> list[int]:
        out = tmp_path / str(duration)
        out.mkdir()
        section = plan_section(out, duration)
        assert section.passed and f"for {duration:g} s;" in section.verdict, section.verdict
        with open(out / "plan.csv", newline="") as table:
            return [int(row["default_cost"]) for row in csv.DictReader(table)]
    short, double = default_costs(1.0), default_costs(2.0)
    assert len(short) == len(double) >= 3
    assert all(abs(b - 2 * a) <= 2 for a, b in zip(short, double)), (short, double)
