#!/usr/bin/env python3
"""What a frame of the live view (harness view) costs: the scene's computation per frame in headless
Chromium (the page's own check, index.html?check=T, which steps the FMUs' WebAssembly modules
through the JavaScript master without drawing) against the harness's master over the native FMUs,
in interleaved rounds of one run. The budget: the thesis scene under 1 ms per frame.

Machine-independent counts beside the times: macro steps and internal FMU steps per frame.

    python benchmarks/view_frame_cost.py [--rounds 5] [--seconds 100]
"""
from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from harness.cosim.master import Master, MasterOptions  # noqa: E402
from harness.cosim.system import load_system  # noqa: E402
from harness.view.page import write_view  # noqa: E402

DRIVER = ROOT / "tests" / "browser" / "drive.mjs"
SCENES = ("thesis_scene", "coupled_pendulums", "spring_chain")
BUDGET_MS = 1.0


def browser_check(page: Path, seconds: float) -> dict:
    result = subprocess.run(["node", str(DRIVER), "check", f"{page.as_uri()}?check={seconds}"], capture_output=True,
                            text=True, cwd=DRIVER.parent, timeout=900)
    if result.returncode != 0:
        raise SystemExit(f"the browser check failed: {result.stderr.strip()[-500:]}")
    checked = json.loads(result.stdout.splitlines()[-1])
    if "error" in checked:
        raise SystemExit(f"the page stopped: {checked['error']}")
    return checked


def native_seconds(scene: Path, seconds: float) -> float:
    with load_system(scene) as system:
        master = Master(system, MasterOptions(stop=seconds, step=system.step))
        try:
            begin = time.perf_counter()
            master.run()
            return time.perf_counter() - begin
        finally:
            master.free()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=100.0, help="simulated time per measurement")
    args = parser.parse_args()
    if shutil.which("node") is None or not (DRIVER.parent / "node_modules" / "playwright-core").is_dir():
        raise SystemExit("needs Node and playwright-core in tests/browser (./run bench installs it)")
    print(f"computation per frame, median of {args.rounds} interleaved rounds of {args.seconds:g} s simulated")
    print(f"{'scene':<18} {'units':>5} {'frames/s':>8} {'macro/frame':>11} {'FMU steps/frame':>15} "
          f"{'browser ms/frame':>16} {'native ms/frame':>15} {'ratio':>6}")
    with tempfile.TemporaryDirectory(prefix="view-bench-") as folder:
        for name in SCENES:
            scene = ROOT / "scenes" / f"{name}.json"
            page = write_view(scene, Path(folder) / name).path
            frame_rate = json.loads(page.read_text().split('id="scene">', 1)[1].split("</script>", 1)[0]
                                    .replace("<\\/", "</"))["frame_rate"]
            browser, native, checked = [], [], None
            for _ in range(args.rounds):
                checked = browser_check(page, args.seconds)
                browser.append(checked["wall_per_second"] / frame_rate * 1e3)
                native.append(native_seconds(scene, args.seconds) / args.seconds / frame_rate * 1e3)
            frames = args.seconds * frame_rate
            fmu_steps = sum(values.get("n_steps", 0) for values in checked["components"].values())
            b, n = statistics.median(browser), statistics.median(native)
            print(f"{name:<18} {len(checked['components']):>5} {frame_rate:>8g} {checked['steps'] / frames:>11.2f} "
                  f"{fmu_steps / frames:>15.2f} {b:>16.4f} {n:>15.4f} {b / n:>6.2f}")
            if name == "thesis_scene":
                print(f"{'':<18} budget {BUDGET_MS:g} ms per frame: {'met' if b < BUDGET_MS else 'NOT met'} "
                      f"({b / BUDGET_MS:.1%} of it; rounds {', '.join(f'{x:.4f}' for x in browser)} ms)")


if __name__ == "__main__":
    main()
