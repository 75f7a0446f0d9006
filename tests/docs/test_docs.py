"""The documentation cannot lie: every code block of README.md and docs/ runs here, in the order of its
page, as a user would run it in the project's folder with the environment `./run demo` makes; every
link between the pages and to the project's files resolves (headings included); the generated
reference pages are current; and the README stays a front door.

How a block runs, by its language:
* `sh`: the commands, by bash with -e, in a folder of the page's own that holds the project's inputs
  (scenes, object files, the build) as links, with `.venv/bin` first on PATH;
* `python`: the script, by the environment's Python, in the same folder;
* `toml` and `json` with `file=NAME` after the language: written to NAME there for the next blocks;
  without a name they must parse;
* `text`: what a command prints or its usage, not run.
An HTML comment before a block tells how it runs here: `<!-- doc-test: needs wasm -->` skips it, with
the reason, where what it needs is missing; `adds ARGS` runs each of its commands with ARGS appended,
for the benchmarks and full sweeps that take minutes (smaller sizes, the same code). Links to the web
are not followed (no network here). A `harness chart` command that asks for what a command of another
page already ran in this test run (the same arguments, as the command line parses them: the same quick
sweep shown in the README, a how-to and an explanation) runs once; the test workers share what ran.
"""
from __future__ import annotations

import ctypes.util
import fcntl
import hashlib
import importlib.util
import json
import os
import re
import shlex
import shutil
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from harness.processes import run_program
from harness.reference_pages import REFERENCE, stale_pages
from harness.view.wasm import WASI_LIBC

from conftest import shared_folder

ROOT = Path(__file__).resolve().parents[2]
# written by the test run itself (the compatibility record): its commands are checked where they are made
GENERATED_BY_TESTS = {ROOT / "docs" / "compatibility.md"}
PAGES = [ROOT / "README.md"] + sorted(p for p in (ROOT / "docs").rglob("*.md") if p not in GENERATED_BY_TESTS)
# what a block's folder holds of the project, as links: the commands' inputs and the build
PROJECT_ENTRIES = ("scenes", "modelDescription", "build", "benchmarks", "docs", "tools", "web", "tests", ".venv")
FENCE = re.compile(r"^```(\S*)(.*)$")
MARKER = re.compile(r"<!--\s*doc-test:\s*(.*?)\s*-->")
QUICK_START = ["./run demo", "./run test"]
NEEDS = {"wasm": (lambda: shutil.which("clang") is not None and WASI_LIBC.exists(),
                  "clang for wasm32-wasi and wasi-libc are not installed (./run installs them as root)"),
         "browser": (lambda: shutil.which("chromium") is not None and shutil.which("clang") is not None
                     and WASI_LIBC.exists() and (ROOT / "tests" / "browser" / "node_modules").exists(),
                     "Debian's Chromium, Playwright and the WebAssembly compiler are needed "
                     "(./run installs them as root)"),
         "mujoco": (lambda: importlib.util.find_spec("mujoco") is not None,
                    "MuJoCo is a benchmark peer, not a test dependency (./run bench installs it)"),
         "heyoka": (lambda: importlib.util.find_spec("heyoka") is not None,
                    "heyoka is a benchmark peer, not a test dependency (./run bench installs it)"),
         "ecos": (lambda: importlib.util.find_spec("ecospy") is not None
                  and ctypes.util.find_library("tbb") is not None,
                  "ecos needs ecospy and Debian's libtbb12 (./run installs it as root)")}


@dataclass
class Block:
    page: Path
    line: int
    language: str
    attributes: dict[str, str]
    text: str
    markers: list[str] = field(default_factory=list)
    seconds: float = 0.0  # what running it took (a command another page ran before takes none)

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def code_blocks(page: Path) -> list[Block]:
    blocks, lines, k = [], page.read_text().splitlines(), 0
    while k < len(lines):
        fence = FENCE.match(lines[k])
        if fence:
            end = next((j for j in range(k + 1, len(lines)) if lines[j].startswith("```")), None)
            assert end is not None, f"{page.relative_to(ROOT)}:{k + 1}: a code block that is never closed"
            attributes = dict(a.split("=", 1) for a in fence.group(2).split() if "=" in a)
            before = next((lines[j] for j in range(k - 1, -1, -1) if lines[j].strip()), "")
            blocks.append(Block(page, k + 1, fence.group(1), attributes, "\n".join(lines[k + 1:end]) + "\n",
                                MARKER.findall(before)))
            k = end
        k += 1
    return blocks


def _page_id(page: Path) -> str:
    return str(page.relative_to(ROOT))


def _workspace(folder: Path) -> None:
    for name in PROJECT_ENTRIES:
        if (ROOT / name).exists():
            (folder / name).symlink_to(ROOT / name)


def _environment() -> dict[str, str]:
    bin_folder = str(Path(sys.executable).parent)
    return {**os.environ, "PATH": bin_folder + os.pathsep + os.environ.get("PATH", ""), "VIRTUAL_ENV":
            str(Path(sys.executable).parent.parent), "PYTHONDONTWRITEBYTECODE": "1"}


def _run(block: Block, folder: Path) -> None:
    if block.language == "sh":
        command = ["bash", "-e", "-c", block.text]
    else:
        script = folder / f"block_{block.line}.py"
        script.write_text(block.text)
        command = [sys.executable, script.name]
    # In a process group of its own, which ends with the test (a time-out left a benchmark running for minutes), and
    # with a temporary folder that goes: some importers (ecos) extract into it and leave it there; it is short and in
    # the system's, as a browser puts its sockets there and a socket's path has a length limit.
    began = time.perf_counter()
    result = run_program(command, cwd=folder, environment=_environment())
    block.seconds += time.perf_counter() - began
    assert result.returncode == 0, (f"{block.where}: exited with {result.returncode}\n{block.text}\n"
                                    f"{result.stdout[-2000:]}\n{result.stderr[-3000:]}")


def _harness_command(line: str) -> str | None:
    """What a `harness chart` command line asks for, as the command line parses it (argument order and
    repeated options aside); None for any other line (another command's files may be a later block's
    input: an SSP archive, a plan)."""
    from harness.cli import build_parser
    words = shlex.split(line)
    if words[:2] != ["harness", "chart"]:
        return None
    try:
        arguments = vars(build_parser().parse_args(words[1:]))
    except SystemExit:
        return None
    return repr(sorted((name, getattr(value, "__name__", value)) for name, value in arguments.items()))


def ran_commands(tmp_path_factory) -> Path:
    """The folder where this test run notes the harness commands that passed: shared by the test workers."""
    return shared_folder(tmp_path_factory, "doc-commands")


def _run_once(block: Block, folder: Path, ran: Path | None) -> None:
    """`_run`; a block of `harness chart` commands one command at a time, each unless the same command passed
    before in this test run (waiting for one that is running)."""
    lines = [line for line in block.text.splitlines() if line.strip()]
    keys = [_harness_command(line) for line in lines] if ran is not None and block.language == "sh" else [None]
    if None in keys:
        _run(block, folder)
        return
    for line, key in zip(lines, keys):
        name = hashlib.sha256(key.encode()).hexdigest()[:24]
        with open(ran / f"{name}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if not (ran / f"{name}.passed").exists():
                command = Block(block.page, block.line, block.language, block.attributes, line + "\n")
                _run(command, folder)
                block.seconds += command.seconds
                (ran / f"{name}.passed").write_text(f"{block.where}: {line}\n")


def run_page(page: Path, folder: Path, ran: Path | None = None, record=None) -> None:
    """Runs the page's blocks in order in `folder`, as its reader would; skips (after the rest ran) the
    blocks whose needs this machine lacks, naming them. `ran`: where passed harness commands are noted
    (`ran_commands`); `record`: pytest's record_property, which gets each block's seconds (in --junitxml's
    report: where the suite's time goes)."""
    _workspace(folder)
    ran_before, ran, skipped = ran, 0, []
    for block in code_blocks(page):
        settings = dict(part.strip().split(" ", 1) for m in block.markers for part in m.split(";"))
        missing = [NEEDS[n][1] for n in settings.get("needs", "").split() if not NEEDS[n][0]()]
        if block.language == "text":
            continue
        if block.language in ("toml", "json"):
            parsed = tomllib.loads if block.language == "toml" else json.loads
            parsed(block.text)  # a block shown as a file must be one
            if "file" in block.attributes:
                (folder / block.attributes["file"]).write_text(block.text)
            continue
        assert block.language in ("sh", "python"), f"{block.where}: a block in {block.language or 'no language'} " \
                                                   "cannot run: mark it sh, python, toml, json or text"
        if block.language == "sh" and block.text.split("\n", 1)[0].startswith("./run "):
            assert block.text.split() == " ".join(QUICK_START).split(), f"{block.where}: ./run takes demo or test"
            continue  # the quick start: checked by test_the_quick_start_is_what_the_tests_run
        if missing:
            skipped.append(f"{block.where}: {missing[0]}")
            continue
        if "adds" in settings:
            block.text = "".join(f"{line} {settings['adds']}\n" if line.strip() else "\n"
                                 for line in block.text.splitlines())
        _run_once(block, folder, ran_before)
        if record is not None:
            record(f"{block.where} seconds", round(block.seconds, 1))
        ran += 1
    if page == ROOT / "README.md":
        assert ran + len(skipped) >= 8  # the common tasks
    if skipped:
        pytest.skip(f"{ran} blocks ran; not run: " + "; ".join(skipped))


# The explanation pages reproduce the measurements (benchmarks, full sweeps): they run in a file of their own,
# tests/docs/test_docs_measurements.py, so that two test workers share the pages' time.
MEASUREMENT_PAGES = sorted((ROOT / "docs" / "explanation").glob("*.md"))


@pytest.mark.parametrize("page", [p for p in PAGES if p not in MEASUREMENT_PAGES], ids=_page_id)
def test_every_block_of_the_page_runs(page, tmp_path, tmp_path_factory, record_property):
    run_page(page, tmp_path, ran_commands(tmp_path_factory), record_property)


def test_the_quick_start_is_what_the_tests_run():
    """The README opens with two commands: the first is what tests/view/test_demo.py runs, the second what CI runs."""
    readme = (ROOT / "README.md").read_text()
    first = code_blocks(ROOT / "README.md")[0]
    assert readme.index("## Quick start") < readme.index("```")
    assert [line for line in first.text.splitlines() if line.strip()] == QUICK_START
    assert '"./run", "demo"' in (ROOT / "tests" / "view" / "test_demo.py").read_text().replace("'", '"')
    assert (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1] == QUICK_START[1]


def test_the_readme_is_short():
    assert len((ROOT / "README.md").read_text().splitlines()) <= 150


LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def _anchors(page: Path) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces as hyphens."""
    anchors, inside = set(), False
    for line in page.read_text().splitlines():
        if line.startswith("```"):
            inside = not inside
        elif not inside and line.startswith("#"):
            title = line.lstrip("#").strip().lower()
            anchors.add(re.sub(r"[^\w\- ]", "", title).replace(" ", "-"))
    return anchors


def _local_links(page: Path) -> list[tuple[str, Path, str]]:
    """The page's links outside code blocks to the project's files: (as written, the file, the anchor).
    Links to the web are not followed here."""
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    links = []
    for target in LINK.findall(text):
        if not re.match(r"[a-z]+:", target):
            path, _, anchor = target.partition("#")
            links.append((target, (page.parent / path).resolve() if path else page, anchor))
    return links


@pytest.mark.parametrize("page", PAGES + sorted(GENERATED_BY_TESTS), ids=_page_id)
def test_no_link_is_broken(page):
    for target, resolved, anchor in _local_links(page):
        assert resolved.exists(), f"{_page_id(page)}: the link {target} names no file"
        if anchor and resolved.suffix == ".md":
            assert anchor in _anchors(resolved), f"{_page_id(page)}: the link {target} names no heading there"


def test_every_page_is_reachable_from_the_readme():
    seen, todo = set(), [ROOT / "README.md"]
    while todo:
        page = todo.pop()
        if page in seen or page.suffix != ".md" or not page.exists():
            continue
        seen.add(page)
        todo += [resolved for _, resolved, _ in _local_links(page)]
    assert [p for p in PAGES if p not in seen] == []


def test_the_generated_reference_pages_are_current(fmu_paths):
    assert stale_pages() == [], "run: python -m harness.reference_pages"
    assert {p.name for p in REFERENCE.glob("*.md")} >= {"cli.md", "methods.md", "objects.md", "scene-file.md",
                                                        "object-file.md", "ssp.md"}


# a command with arguments; a command's bare name (`harness view`) is a name, not a command line
COMMAND_IN_TEXT = re.compile(r"`((?:harness|python -m harness) [\w-]+ [^`]+|\.venv/bin/\S+ [^`]+|\./run \w[^`]*)`")


@pytest.mark.parametrize("page", PAGES, ids=_page_id)
def test_commands_are_in_blocks_that_run(page):
    """A command line written inside a sentence would not run here: commands go in blocks."""
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    commands = [c for c in COMMAND_IN_TEXT.findall(text)
                if c not in QUICK_START  # the README's two, which its first block holds
                and not re.search(r"\b[A-Z]{2,}\b", c)]  # a usage pattern with placeholders (SCENE, FILE.ssp)
    assert commands == []
