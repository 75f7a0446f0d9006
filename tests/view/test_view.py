"""`harness view`: the scene live in a browser. The page is loaded in Debian's Chromium, headless,
driven by Playwright (tests/browser/drive.mjs): its headless check (index.html?check=T) must end
where the harness's master over the native FMUs ends, for uncoupled and coupled scenes and every
master algorithm; a person's drag must restart the object from where it was dropped, at rest, and
the steps after it must be those of the native FMU from that start; a method or step chosen on the
page must be the one the FMU runs; the page must load nothing from the network, opened as a file
and served over HTTP. The screenshots go to build/screenshots/ (the README shows copies).

Agreement is to rounding, not bit for bit: the modules link wasi-libc's mathematical functions
(tests/view/test_wasm.py measures where they differ from glibc's)."""
from __future__ import annotations

import functools
import json
import math
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from harness.cosim.algorithm_registry import REGISTRY
from harness.cli import main
from harness.cosim.master import Master, MasterOptions
from harness.cosim.system import load_system
from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.fmus import PROJECT_ROOT, build_dir
from harness.fmi.methods import METHODS
from harness.objects.thesis.reference import exact_simple_pendulum
from harness.view.wasm import WASI_LIBC

PAGE_ALGORITHMS = [entry.name for entry in REGISTRY if entry.page]

NODE = shutil.which("node")
DRIVER = PROJECT_ROOT / "tests" / "browser" / "drive.mjs"
CHROMIUM = Path("/usr/bin/chromium")
SCENES = PROJECT_ROOT / "scenes"
SCREENSHOTS = build_dir() / "screenshots"


def needs_browser() -> None:
    if NODE is None:
        pytest.skip("Node is not installed")
    if not CHROMIUM.exists():
        pytest.skip("Debian's chromium is not installed (./run installs it as root)")
    if not (DRIVER.parent / "node_modules" / "playwright-core").is_dir():
        pytest.skip("playwright-core is not installed in tests/browser (./run test installs it with npm ci)")
    needs_wasm_tools()


def needs_wasm_tools() -> None:
    if shutil.which("clang") is None or not WASI_LIBC.exists():
        pytest.skip("needs clang with the wasm32-wasi target and Debian's wasi-libc (./run installs them as root)")


def drive(*args: str) -> dict:
    result = subprocess.run([NODE, str(DRIVER), *args], capture_output=True, text=True, timeout=600,
                            cwd=DRIVER.parent)
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.splitlines()[-1])


@functools.cache
def page(scene: str) -> Path:
    """The scene's page, written once per test process through the command line."""
    out = build_dir() / "test-view" / scene
    assert main(["view", str(SCENES / f"{scene}.json"), "--out", str(out)]) == 0
    return out / "index.html"


def native_end(scene: str, stop: float, **options) -> dict[str, float]:
    """Every output at `stop` from the harness's master over the native FMUs, in plain macro steps of the scene's
    step as the page takes them."""
    with load_system(SCENES / f"{scene}.json") as system:
        master = Master(system, MasterOptions(stop=stop, step=system.step, **{"contact_steps": 0, **options}))
        try:
            result = master.run()
        finally:
            master.free()
    return dict(zip(result.columns, result.values[-1]))


def assert_agrees(checked: dict, expected: dict[str, float], bound: float) -> float:
    assert not checked.get("problems"), checked.get("problems")
    assert "error" not in checked, checked.get("error")
    assert checked["time"] == pytest.approx(expected["time"], abs=1e-12)
    names = {f"{c}.{v}" for c, values in checked["components"].items() for v in values}
    assert names == set(expected) - {"time"}  # every output of every component, nothing else
    worst = 0.0
    for component, values in checked["components"].items():
        for name, value in values.items():
            reference = expected[f"{component}.{name}"]
            if float(reference).is_integer() and name.startswith("n_"):  # counters: exactly
                assert value == reference, (component, name)
            worst = max(worst, abs(value - reference) / (1 + abs(reference)))
    assert worst <= bound
    assert checked["wall_per_second"] > 0
    return worst


@pytest.mark.parametrize("scene, stop, bound", [("thesis_scene", 2.0, 1e-10), ("double_and_cart", 3.0, 1e-10),
                                                ("spring_chain", 2.0, 1e-10), ("string_pendulum", 2.0, 1e-10),
                                                ("newtons_cradle", 2.0, 1e-9), ("contact_cradle", 0.3, 1e-8),
                                                ("colliding_carts", 0.8, 1e-8), ("double_strikes_ball", 0.62, 1e-8)])
def test_the_headless_check_ends_where_the_native_master_does(scene, stop, bound):
    needs_browser()
    checked = drive("check", f"{page(scene).as_uri()}?check={stop}")
    assert_agrees(checked, native_end(scene, stop), bound)
    assert checked["steps"] == math.ceil(stop / load_system(SCENES / f"{scene}.json").step - 1e-9)


@pytest.mark.parametrize("algorithm", PAGE_ALGORITHMS)
@pytest.mark.parametrize("extrapolation", ["hold", "linear"])
def test_the_javascript_master_is_the_harness_master(algorithm, extrapolation):
    needs_browser()
    checked = drive("check", f"{page('coupled_pendulums').as_uri()}?check=3&algorithm={algorithm}"
                             f"&extrapolation={extrapolation}")
    # the same calls in the same order: only the libm's last bits part them
    assert_agrees(checked, native_end("coupled_pendulums", 3.0, algorithm=algorithm, extrapolation=extrapolation),
                  1e-12)


def test_the_page_is_served_over_http_as_from_a_file():
    needs_browser()
    index = page("coupled_pendulums")
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "http.server", str(port), "--bind", "127.0.0.1"],
                              cwd=index.parent, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(100):
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
                break
            except OSError:
                time.sleep(0.05)
        served = drive("check", f"http://127.0.0.1:{port}/index.html?check=1")
    finally:
        server.terminate()
        server.wait(10)
    from_file = drive("check", f"{index.as_uri()}?check=1")
    assert not served["problems"] and not from_file["problems"]  # nothing fetched from anywhere else
    assert served["components"] == from_file["components"]


def test_the_page_holds_everything_it_needs():
    needs_wasm_tools()
    text = page("thesis_scene").read_text()
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", text)  # no resource from elsewhere
    assert not re.search(r"""\bimport\s*\(|^\s*import\s""", text, re.MULTILINE)  # one script, no module to fetch
    scene = json.loads(re.search(r'<script type="application/json" id="scene">(.*?)</script>', text, re.S).group(1))
    assert set(scene["modules"]) == {"SimplePendulum", "SpringPendulum", "DoublePendulum"}
    assert all(len(m["wasm"]) > 100_000 for m in scene["modules"].values())


def run_native(fmu: Path, start: dict, steps: int, H: float, outputs: list[str]) -> dict[str, float]:
    with FmuInstance(fmu) as instance:
        instance.initialize(0.0, **start)
        for k in range(steps):
            assert instance.do_step(k * H, (k + 1) * H - k * H) == 0
        return dict(zip(outputs, instance.get(*outputs)))


def test_a_dragged_mass_restarts_the_object_from_where_it_was_dropped():
    needs_browser()
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    target = [-math.sin(1.0), -math.cos(1.0)]  # the simple pendulum's bob at -1 rad
    tip = [0.9 * math.sin(0.3) + 0.9 * math.sin(-0.4), 0.9 - 0.9 * math.cos(0.3) - 0.9 * math.cos(-0.4)]
    plan = [{"drag": ["simple", "x", "y", target]}, {"snapshot": "dropped"}, {"start": ["start", "simple"]},
            {"drag": ["double", "x2", "y2", tip]}, {"snapshot": "dropped2"}, {"start": ["start2", "double"]},
            {"step": 5}, {"snapshot": "stepped"},
            {"screenshot": str(SCREENSHOTS / "view_thesis_scene_dragged.png")}]
    seen = session("thesis_scene", plan)
    scene = load_system(SCENES / "thesis_scene.json")
    pixel = seen["metres_per_pixel"]
    dropped, start = seen["dropped"]["components"]["simple"], seen["start"]
    assert seen["dropped"]["time"] == 0
    assert math.dist([dropped["x"], dropped["y"]], target) <= pixel  # where the mouse let go, to a pixel
    assert start.get("omega", 0) == 0 and dropped["omega"] == 0  # at rest, as the scene starts it
    assert start["phi"] == pytest.approx(-1.0, abs=pixel)
    double = seen["dropped2"]["components"]["double"]
    assert math.dist([double["x2"], double["y2"]], tip) <= pixel
    assert seen["dropped2"]["components"]["double"]["omega1"] == 0 == seen["dropped2"]["components"]["double"]["omega2"]
    # the first drop stays: the scene restarted with both new starts
    assert seen["dropped2"]["components"]["simple"]["phi"] == dropped["phi"]
    # five steps on from there are the native FMUs' from the same starts
    H = scene.step
    for name, start_values in (("simple", seen["start"]), ("double", seen["start2"])):
        component = scene.component(name)
        got = seen["stepped"]["components"][name]
        expected = run_native(component.fmu, start_values, 5, H, list(got))
        for variable, value in got.items():
            assert value == pytest.approx(expected[variable], rel=1e-12, abs=1e-12), (name, variable)
    assert seen["stepped"]["time"] == pytest.approx(5 * H)
    assert (SCREENSHOTS / "view_thesis_scene_dragged.png").stat().st_size > 10_000


def test_a_spherical_pendulum_is_drawn_and_dragged_as_its_scene_traces_it():
    """Traced from above (x, z), it is drawn and dragged from above, and keeps its spin: from rest it
    would fall through its coordinates' pole."""
    needs_browser()
    target = [0.3, 0.2]
    seen = session("spherical_pendulum", [{"drag": ["bob", "x", "z", target]}, {"snapshot": "dropped"},
                                          {"start": ["start", "bob"]}, {"step": 50}, {"problem": "problem"},
                                          {"snapshot": "later"}])
    bob = seen["dropped"]["components"]["bob"]
    assert math.dist([bob["x"], bob["z"]], target) <= seen["metres_per_pixel"]
    spin = load_system(SCENES / "spherical_pendulum.json").component("bob").start.get("psi_dot", 3.0)
    assert bob["psi_dot"] == spin and bob["theta_dot"] == 0
    assert seen["problem"] == "" and seen["later"]["time"] == pytest.approx(0.5)


def test_the_cradle_is_playable_two_balls_in_two_out():
    """Newton's cradle on the page: ball 2 dragged out beside ball 1 (a drop into ball 1 is refused by
    the FMU, so the drag stops where they touch), let go: the impacts in the WebAssembly FMU are the
    native FMU's, and two balls swing out on the other side."""
    needs_browser()
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    L, R, phi0 = 0.3, 0.02, -0.5  # scenes/newtons_cradle.json, modelDescription/NewtonsCradle.toml
    beside = [-2 * R + L * math.sin(phi0), -L * math.cos(phi0)]
    into = [-2 * R + L * math.sin(phi0 - 0.2), -L * math.cos(phi0 - 0.2)]  # through ball 1
    steps = 90  # 0.45 s: past the impact at a quarter period (0.28 s)
    ball1 = [-4 * R + L * math.sin(phi0), -L * math.cos(phi0)]
    # Restart first: the page ran from its load until the session paused it, and a drag starts every ball
    # from where it is (past a quarter period, balls 4 and 5 would already be out)
    plan = [{"click": "#restart"}, {"drag": ["cradle", "ball1_x", "ball1_y", ball1]},
            {"drag": ["cradle", "ball2_x", "ball2_y", into]},
            {"snapshot": "pushed"}, {"drag": ["cradle", "ball2_x", "ball2_y", beside]}, {"snapshot": "dropped"},
            {"start": ["start", "cradle"]}, {"step": steps}, {"snapshot": "later"},
            {"screenshot": str(SCREENSHOTS / "view_newtons_cradle.png")}]
    seen = session("newtons_cradle", plan)
    pixel = seen["metres_per_pixel"]
    pushed = seen["pushed"]["components"]["cradle"]
    assert -1e-12 <= pushed["contact12_gap"] < 1e-3  # stopped at ball 1 (to the FMU's tolerance), not through it
    dropped = seen["dropped"]["components"]["cradle"]
    assert math.dist([dropped["ball2_x"], dropped["ball2_y"]], beside) <= pixel
    component = load_system(SCENES / "newtons_cradle.json").component("cradle")
    got = seen["later"]["components"]["cradle"]
    expected = run_native(component.fmu, seen["start"], steps, load_system(SCENES / "newtons_cradle.json").step,
                          list(got))
    for variable, value in got.items():
        assert value == pytest.approx(expected[variable], rel=1e-9, abs=1e-9), variable
    assert got["n_events"] >= 2
    assert got["phi4"] > 0.3 and got["phi5"] > 0.3  # two out
    assert max(abs(got[f"phi{i}"]) for i in (1, 2, 3)) < 0.05  # two at rest behind them (and ball 3)
    assert (SCREENSHOTS / "view_newtons_cradle.png").stat().st_size > 10_000


def session(scene: str, plan: list[dict]) -> dict:
    url = page(scene).as_uri()  # writes build/test-view, where the plan goes too
    plan_file = build_dir() / "test-view" / f"{scene}-plan.json"
    plan_file.write_text(json.dumps(plan))
    seen = drive("session", url, str(plan_file))
    assert not seen["problems"], seen["problems"]
    return seen


def test_the_method_and_step_chosen_on_the_page_are_those_the_fmu_runs():
    needs_browser()
    plan = [{"set": ["simple", "solver", "euler"]}, {"set": ["simple", "h", 0.01]}, {"step": 3},
            {"snapshot": "euler"}, {"start": ["start", "simple"]},
            {"set": ["simple", "h", -1]}, {"problem": "refused"}, {"start": ["kept", "simple"]}]
    seen = session("thesis_scene", plan)
    component = load_system(SCENES / "thesis_scene.json").component("simple")
    assert seen["start"]["solver"] == 1 and seen["start"]["h"] == 0.01  # euler's item, the new step
    got = seen["euler"]["components"]["simple"]
    expected = run_native(component.fmu, dict(component.start, solver="euler", h=0.01), 3, 0.04, list(got))
    for variable, value in got.items():
        assert value == pytest.approx(expected[variable], rel=1e-12, abs=1e-12), variable
    assert got["n_steps"] == 12  # 3 steps of 0.04 s at h = 0.01
    # a step the FMU refuses: its message on the page, the step before kept
    assert "h" in seen["refused"] and "-1" in seen["refused"]
    assert seen["kept"]["h"] == 0.01


def test_the_order_chosen_on_the_page_is_the_one_the_fmu_runs():
    """taylor and gbs get an order field (taylor_order, gbs_columns); a value the FMU refuses or that is no
    32-bit integer is reported on the page and the order before kept."""
    needs_browser()
    plan = [{"set": ["simple", "solver", "taylor"]}, {"set": ["simple", "taylor_order", 8]},
            {"set": ["simple", "tol", 0]}, {"set": ["simple", "h", 0.04]}, {"step": 3}, {"snapshot": "taylor"},
            {"start": ["start", "simple"]},
            {"set": ["simple", "taylor_order", 31]}, {"problem": "refused"},
            {"set": ["simple", "taylor_order", 8.5]}, {"problem": "fraction"},
            {"set": ["simple", "taylor_order", 2 ** 32 + 8]}, {"problem": "wide"}, {"start": ["kept", "simple"]},
            {"set": ["simple", "solver", "gbs"]}, {"set": ["simple", "gbs_columns", 3]}, {"start": ["gbs", "simple"]}]
    seen = session("thesis_scene", plan)
    solvers = [m.name for m in METHODS]
    assert seen["start"]["solver"] == solvers.index("taylor") + 1 and seen["start"]["taylor_order"] == 8
    component = load_system(SCENES / "thesis_scene.json").component("simple")
    got = seen["taylor"]["components"]["simple"]
    expected = run_native(component.fmu, dict(component.start, solver="taylor", taylor_order=8, tol=0.0, h=0.04), 3,
                          0.04, list(got))
    for variable, value in got.items():
        assert value == pytest.approx(expected[variable], rel=1e-12, abs=1e-12), variable
    assert got["n_steps"] == 3  # 3 steps of 0.04 s at h = 0.04
    assert "taylor_order" in seen["refused"] and "31" in seen["refused"] and "30" in seen["refused"]
    assert "8.5" in seen["fraction"] and "integer" in seen["fraction"]
    assert str(2 ** 32 + 8) in seen["wide"] and "integer" in seen["wide"]
    assert seen["kept"]["taylor_order"] == 8
    assert seen["gbs"]["solver"] == solvers.index("gbs") + 1 and seen["gbs"]["gbs_columns"] == 3


def test_a_coupled_scene_runs_live_and_is_photographed():
    needs_browser()
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    for scene in ("thesis_scene", "spring_chain"):
        shot = SCREENSHOTS / f"view_{scene}.png"
        seen = drive("shot", page(scene).as_uri(), str(shot), "2")
        assert not seen["problems"] and not seen["problem"], seen
        assert seen["time"] > 0.5  # it moved on by itself, at the scene's frame rate
        assert shot.stat().st_size > 10_000


def test_a_bad_check_time_is_reported_on_the_page():
    needs_browser()
    checked = drive("check", f"{page('coupled_pendulums').as_uri()}?check=soon")
    assert "check=soon" in checked["error"]
    checked = drive("check", f"{page('coupled_pendulums').as_uri()}?check=1&algorithm=newton")
    assert "newton" in checked["error"]
    checked = drive("check", f"{page('coupled_pendulums').as_uri()}?check=1e12")  # bounded as the harness's runs
    assert "more than the 10000000 allowed" in checked["error"]


def test_the_exact_pendulum_in_javascript_is_scipys():
    if NODE is None:
        pytest.skip("Node is not installed")
    cases = [(0.1, 0.37), (0.5, 1.0), (2.5, 7.3), (-3.0, 11.1), (3.1, 250.0)]
    script = ("import { exactSimplePendulum } from " + json.dumps((PROJECT_ROOT / "web" / "exact.mjs").as_uri())
              + "; console.log(JSON.stringify(" + json.dumps(cases)
              + ".map(([p, t]) => exactSimplePendulum(p, t, 9.81, 1.3))));")
    result = subprocess.run([NODE, "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    for (phi0, t), (phi, omega) in zip(cases, json.loads(result.stdout)):
        reference_phi, reference_omega = exact_simple_pendulum(phi0, t, 9.81, 1.3)
        assert phi == pytest.approx(float(reference_phi), abs=1e-11)
        assert omega == pytest.approx(float(reference_omega), abs=1e-10)


def test_view_refuses_what_it_cannot_show(tmp_path, capsys):
    needs_wasm_tools()
    scene = json.loads((SCENES / "coupled_pendulums.json").read_text())
    scene["components"]["left"]["fmu"] = "fmi3/SimplePendulum"
    (tmp_path / "fmi3.json").write_text(json.dumps(scene))
    out = tmp_path / "out"
    assert main(["view", str(tmp_path / "fmi3.json"), "--out", str(out)]) == 2
    assert "FMI 2.0 Co-Simulation" in capsys.readouterr().err
    assert not out.exists()  # nothing made for a refused scene
    (tmp_path / "file").write_text("x")
    assert main(["view", str(SCENES / "thesis_scene.json"), "--out", str(tmp_path / "file")]) == 2
    assert "is a file" in capsys.readouterr().err
    scene = json.loads((SCENES / "thesis_scene.json").read_text())
    scene["camera"]["layout"] = "stacked"
    (tmp_path / "layout.json").write_text(json.dumps(scene))
    assert main(["view", str(tmp_path / "layout.json"), "--out", str(out)]) == 2
    assert "'layout'" in capsys.readouterr().err
    scene = json.loads((SCENES / "thesis_scene.json").read_text())
    scene["components"]["simple"]["start"]["h"] = -0.1
    (tmp_path / "start.json").write_text(json.dumps(scene))
    assert main(["view", str(tmp_path / "start.json"), "--out", str(out)]) == 2
    assert "simple" in capsys.readouterr().err
    assert not out.exists()


def test_names_and_texts_from_the_scene_are_only_text(tmp_path):
    """A description holding <!-- and </script>, components named __proto__ and constructor: the page
    still runs and ends where the native master does."""
    needs_browser()
    scene = json.loads((SCENES / "coupled_pendulums.json").read_text())
    renames = {"left": "__proto__", "right": "constructor"}
    text = json.dumps(scene)
    for old, new in renames.items():
        text = text.replace(f'"{old}', f'"{new}')
    scene = json.loads(text)
    scene["description"] = "a <!-- comment and </script><script>document.title='owned'</script> in text"
    scene["components"]["spring"]["fmu"] = str(build_dir() / "fmus" / "Spring.fmu")
    for name in renames.values():
        scene["components"][name]["fmu"] = str(build_dir() / "fmus" / "SimplePendulum.fmu")
    path = tmp_path / "odd.json"
    path.write_text(json.dumps(scene))
    assert main(["view", str(path), "--out", str(tmp_path / "view")]) == 0
    checked = drive("check", f"{(tmp_path / 'view' / 'index.html').as_uri()}?check=1")
    assert set(checked["components"]) == {"spring", "__proto__", "constructor"}
    with load_system(path) as system:
        master = Master(system, MasterOptions(stop=1.0, step=system.step))
        try:
            result = master.run()
        finally:
            master.free()
    assert_agrees(checked, dict(zip(result.columns, result.values[-1])), 1e-12)
    seen = drive("shot", (tmp_path / "view" / "index.html").as_uri(), str(tmp_path / "odd.png"), "1")
    assert not seen["problems"] and not seen["problem"]


def test_dragged_angles_stay_in_one_turn_and_typed_nonsense_is_refused():
    needs_browser()
    plan = [{"drag": ["simple", "x", "y", [math.sin(2.5), -math.cos(2.5)]]},
            {"drag": ["simple", "x", "y", [math.sin(-2.5), -math.cos(-2.5)]]},  # over the top: phi passes pi
            {"start": ["start", "simple"]},
            {"set": ["simple", "h", ""]}, {"problem": "empty"}, {"start": ["kept", "simple"]}]
    seen = session("thesis_scene", plan)
    assert seen["start"]["phi"] == pytest.approx(-2.5, abs=seen["metres_per_pixel"])  # not 2 pi - 2.5
    assert "h = '' is not a number" in seen["empty"] and seen["kept"].get("h", 0.008) == 0.008


@pytest.mark.parametrize("change, message", [
    ({"step": 1e-7}, "macro steps per frame"), ({"step": 100.0}, "less than once a minute"),
    ({"camera": {"frame_rate": 1e-300}}, "macro steps per frame"),
    ({"connections": [["simple.x", "double.nope"]]}, "nope"),
    ({"connections": [["simple.n_rhs", "double.F_x"]]}, "n_rhs")])
def test_view_refuses_a_scene_the_page_could_not_run(tmp_path, capsys, change, message):
    scene = json.loads((SCENES / "thesis_scene.json").read_text())
    for key, value in change.items():
        scene[key] = dict(scene[key], **value) if isinstance(value, dict) else value
    for component in scene["components"].values():
        component["fmu"] = str(build_dir() / "fmus" / f"{component['fmu']}.fmu")
    (tmp_path / "scene.json").write_text(json.dumps(scene))
    begin = time.perf_counter()
    assert main(["view", str(tmp_path / "scene.json"), "--out", str(tmp_path / "out")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    assert time.perf_counter() - begin < 5  # refused before any module is built


def test_view_never_writes_over_its_inputs(tmp_path, capsys):
    scene = tmp_path / "scene.json"
    shutil.copy(SCENES / "coupled_pendulums.json", scene)
    before = scene.read_bytes()
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "index.html").symlink_to(scene)
    assert main(["view", str(scene), "--out", str(tmp_path / "out")]) == 2
    assert "is this command's input" in capsys.readouterr().err
    assert scene.read_bytes() == before


def test_an_interrupted_view_ends_its_compilers_and_leaves_nothing(tmp_path):
    needs_wasm_tools()
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    cache = tmp_path / "cache"  # empty: the modules are compiled (the run's own cache has them)
    environment = dict(os.environ, TMPDIR=str(scratch), PENDULUM_WASM_CACHE=str(cache))
    # SIGINT as a terminal delivers it: a test worker may run with it ignored, which its children inherit
    process = subprocess.Popen([sys.executable, "-m", "harness", "view", str(SCENES / "thesis_scene.json"), "--out",
                                str(tmp_path / "out")], env=environment, cwd=PROJECT_ROOT,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 60
    while time.time() < deadline and not any(scratch.glob("wasm-*/module.wasm.tmp*")) \
            and not _compilers_in(scratch):
        time.sleep(0.05)
    assert _compilers_in(scratch), "no compiler started"
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=30)
    assert process.returncode == 130, err
    time.sleep(0.2)
    assert not _compilers_in(scratch)  # every clang ended with the harness, not after it
    assert list(scratch.iterdir()) == []  # its work folders removed
    assert not (tmp_path / "out").exists()
    assert not list(cache.glob(".*.part"))  # no half-written module in the cache


def _compilers_in(scratch: Path) -> list[str]:
    """Running processes whose command line names the folder (the clang jobs of one view)."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and str(scratch) in (proc / "cmdline").read_bytes().decode(errors="replace"):
                found.append(proc.name)
        except OSError:
            continue
    return found


# ---------------------------------------------------------------- the modules' cache

def test_a_module_is_built_once_and_then_taken_from_the_cache(fmu_paths, tmp_path, monkeypatch):
    """The live view's modules are kept under the name of what went into them: the same FMU again compiles
    nothing and gives the same bytes; an entry that is no module is built again and replaced; an empty
    PENDULUM_WASM_CACHE keeps none."""
    needs_wasm_tools()
    from harness.view import wasm
    cache = tmp_path / "cache"
    monkeypatch.setenv("PENDULUM_WASM_CACHE", str(cache))
    compiled, compile_all = [], wasm.run_programs

    def counting(commands, parallel):
        compiled.extend(commands)
        return compile_all(commands, parallel)
    monkeypatch.setattr(wasm, "run_programs", counting)
    fmu = fmu_paths["SimplePendulum"]
    first = wasm.build_modules([fmu])[fmu]
    assert first.startswith(b"\0asm") and len(compiled) == 1
    [entry] = cache.glob("*.wasm")
    assert entry.read_bytes() == first
    assert wasm.build_modules([fmu, fmu_paths["SimplePendulum"]])[fmu] == first and len(compiled) == 1
    entry.write_bytes(b"half a modu")
    assert wasm.build_modules([fmu])[fmu] == first and len(compiled) == 2  # the same inputs, the same bytes
    assert entry.read_bytes() == first and sorted(cache.iterdir()) == [entry]  # no part file left
    monkeypatch.setenv("PENDULUM_WASM_CACHE", "")
    assert wasm.build_modules([fmu])[fmu] == first and len(compiled) == 3


def test_the_cache_key_is_every_byte_that_goes_into_a_module(tmp_path):
    """Where the work folder lies does not count; the compiler's identity, a flag, which files are compiled and a
    header's byte do."""
    from harness.view.wasm import module_key
    work, moved = tmp_path / "work", tmp_path / "elsewhere"
    (work / "sources").mkdir(parents=True)
    (work / "sources" / "model.c").write_text('#include "model.h"\nint n = N;\n')
    (work / "sources" / "model.h").write_text("#define N 1\n")
    (work / "sources" / "extra.c").write_text("int m;\n")
    command = ["clang", "-O3", f"-I{work / 'sources'}", str(work / "sources" / "model.c"),
               str(work / "sources" / "extra.c"), "-o", str(work / "module.wasm")]
    key = module_key("clang version 14.0.6", command, work)
    shutil.copytree(work, moved)
    assert module_key("clang version 14.0.6", [c.replace(str(work), str(moved)) for c in command], moved) == key
    assert module_key("clang version 15.0.7", command, work) != key
    assert module_key("clang version 14.0.6", [command[0], "-O2", *command[2:]], work) != key
    assert module_key("clang version 14.0.6", [*command[:4], *command[5:]], work) != key  # extra.c not compiled
    (work / "sources" / "model.h").write_text("#define N 2\n")
    assert module_key("clang version 14.0.6", command, work) != key


def test_the_cache_keeps_the_modules_used_last(tmp_path, monkeypatch):
    """Past its bound the cache lets go of the module used longest ago; reading a module counts as a use."""
    from harness.view import wasm
    monkeypatch.setattr(wasm, "CACHED_MODULES", 2)
    module = wasm.WASM_MAGIC + b"\x01\0\0\0"
    for k, key in enumerate(("a", "b")):
        wasm._keep(tmp_path, key, module)
        os.utime(tmp_path / f"{key}.wasm", (1000.0 + k, 1000.0 + k))
    assert wasm._cached(tmp_path, "a") == module  # a is now the one used last
    wasm._keep(tmp_path, "c", module)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.wasm", "c.wasm"]
    (tmp_path / "c.wasm").write_bytes(b"<html>")
    assert wasm._cached(tmp_path, "c") is None and wasm._cached(tmp_path, "missing") is None


def test_the_page_stops_a_step_deep_into_a_contact_by_name(tmp_path):
    """The page's master makes the harness's energy check (harness/cosim/contact_guard.py): Newton's cradle at plain
    macro steps of a millisecond stops at the step that enters the strike, naming the contact and a step that would
    do, at the time the harness's master stops (which the page's plain steps are, with --contact-steps 0)."""
    needs_browser()
    import re

    from harness.scene.contact_scenes import released_cradle
    data = released_cradle(1e-3)
    scene = tmp_path / "cradle.json"
    scene.write_text(json.dumps(data))
    assert main(["view", str(scene), "--out", str(tmp_path / "view")]) == 0
    checked = drive("check", f"{(tmp_path / 'view' / 'index.html').as_uri()}?check=0.5")
    message = checked.get("error", "")
    assert (message.startswith("contact12: the macro step of 0.00100 s from t = ")
            and "a macro step of at most" in message)
    with load_system(scene) as system:
        with Master(system, MasterOptions(stop=0.5, step=1e-3, contact_steps=0)) as master:
            stopped = master.run().stopped_at
    assert float(re.search(r"from t = ([0-9.e+-]+) s", message).group(1)) == pytest.approx(stopped, abs=1e-9)
