"""The harness and its command line against bad input: arguments and option values, scene files, SSD files and
SSP archives, FMUs and object files that are broken, hostile or ask for what cannot be carried out, outputs that
must not be written where they are asked for, a full disk or a folder that refuses writing, and interrupts at any
moment. Whatever the input, the exit code is 0, 1 or 2 (3 would be a fault of the harness, 130 an interrupt), a
user error (2) is one line on stderr that names what is wrong, there is no traceback, no temporary folder or file
is left behind, a CSV that was written is well formed (a unique header, every row as long, every cell a finite
number), the rows written so far are kept, and neither an earlier result nor an input is replaced.

Generated inputs (hypothesis, derandomized: the same ones each run) and crafted ones run the command line in this
process (main() is its error boundary), with tempfile's folder pointed at an empty one per example, so that
anything left behind is seen. Broken FMUs and SSDs, runs that stop, and interrupts run it as a user does, in a
process of its own: an interrupt ends the run with exit code 130 and one line, its temporary files gone and the
workers, compilers and builds it started ended. The master, run here directly, releases every FMU state it saved
once it has served (counted through the FMUs' memory callbacks), through rollbacks and failed steps alike."""
from __future__ import annotations

import contextlib
import io
import itertools
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from harness import archives
from harness.cli import main
from harness.fmi.fmus import PROJECT_ROOT, build_dir

from conftest import hostile


# ================ generated and crafted input, the command line run in this process ===================================

SCENE = PROJECT_ROOT / "scenes" / "coupled_pendulums.json"
counter = itertools.count()


class Outcome:
    def __init__(self, code: int, stdout: str, stderr: str):
        self.code, self.stdout, self.stderr = code, stdout, stderr

    def __repr__(self) -> str:
        return f"exit {self.code}\nstdout: {self.stdout[-500:]}\nstderr: {self.stderr[-1500:]}"


def cli(argv: list[str], workspace: Path) -> Outcome:
    """Runs the command line in this process; checks the promises that hold for every input."""
    watched = workspace / f"tmp{next(counter)}"
    watched.mkdir()
    before = set(workspace.iterdir())
    stdout, stderr = io.StringIO(), io.StringIO()
    saved = tempfile.tempdir
    tempfile.tempdir = str(watched)
    try:
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
            try:
                code = main(argv)
            except SystemExit as stop:  # argparse's usage errors and --help
                code = stop.code if isinstance(stop.code, int) else 2
    finally:
        tempfile.tempdir = saved
    outcome = Outcome(code, stdout.getvalue(), stderr.getvalue())
    assert code in (0, 1, 2), outcome
    assert "Traceback" not in outcome.stderr, outcome
    if code == 2:
        assert len(outcome.stderr.strip().splitlines()) == 1, outcome
    left = list(watched.iterdir())
    assert not left, f"left behind in the temporary folder: {left}\n{outcome}"
    watched.rmdir()
    stray = [p for p in set(workspace.iterdir()) - before if p.name.endswith(".part")]
    assert not stray, f"temporary output files left: {stray}"
    return outcome


def well_formed_csv(path: Path) -> int:
    """Rows of a CSV the harness wrote; fails unless it is well formed."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    assert header[0] == "time" and len(set(header)) == len(header) and all(header), header
    for line in lines[1:]:
        cells = line.split(",")
        assert len(cells) == len(header), line
        assert all(math.isfinite(float(cell)) for cell in cells), line
    return len(lines) - 1


def output_checked(outcome: Outcome, out: Path) -> None:
    if out.exists():
        rows = well_formed_csv(out)
        if outcome.code == 0:
            assert rows >= 2, outcome
    else:
        assert outcome.code != 0, outcome


@pytest.fixture(scope="module")
def workspace(tmp_path_factory, fmu_paths) -> Path:
    return tmp_path_factory.mktemp("hostile")


# ---- command-line arguments ---------------------------------------------------------------------

# Numbers as text, chosen so that every run they allow is short: a few points, or refused at once.
number_text = st.one_of(
    st.sampled_from(["inf", "-inf", "nan", "NaN", "-0", "0", "-1", "1e-300", "5e-324", "1e-12", "0.05", "0.02",
                     "1e15", "1e308", "1.7976931348623157e308", "abc", "", " ", "0x10", "1_0", "1e", "--1",
                     "4294967301", "-2147483649", "2.5"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr).filter(lambda t: not 0.1 < abs(float(t)) < 1e14),
    st.text(max_size=12))
variable_names = st.sampled_from(["phi", "omega", "L", "m", "g", "d", "h", "tol", "solver", "model", "F_x",
                                  "anchor_x", "n_rhs", "x", "nothing", "", "phi=1", "é", "a,b"])
value_text = st.one_of(number_text, st.sampled_from(["rk4", "ab6", "rkf45", "euler", "linear", "RK4", "ab7"]))


def mostly(valid, hostile):
    """Three in four draws valid: so that a run with several arguments often gets past the parser
    and its extreme values reach the FMU."""
    return st.tuples(st.sampled_from([True, True, True, False]), valid, hostile).map(
        lambda draw: draw[1] if draw[0] else draw[2])


# In-range extremes of the SimplePendulum's settable values, as --set text.
extreme_assignments = st.sampled_from([
    ("phi", "3.141592653589793"), ("phi", "-1e300"), ("omega", "1e300"), ("omega", "1e9"), ("L", "1e-9"),
    ("L", "1.7e308"), ("m", "1e-9"), ("m", "1e300"), ("g", "0"), ("g", "1e300"), ("d", "1e300"), ("d", "0"),
    ("tol", "1e-14"), ("tol", "1"), ("h", "1e-9"), ("h", "1e300"), ("F_x", "1e300"), ("F_x", "-1.7e308"),
    ("anchor_x", "1e308"), ("solver", "rkf45"), ("solver", "ab6"), ("solver", "12"), ("solver", "1"),
    ("model", "linear"), ("model", "2")])


@given(stop=mostly(st.sampled_from(["0.05", "0.02", "1e-12", "0.011", "1e3"]), number_text),
       step=mostly(st.sampled_from(["0.01", "0.05", "1e-3", "1e3"]), number_text),
       h=st.one_of(st.none(), st.none(), st.sampled_from(["1e-9", "0.001", "1", "1e300"]), number_text),
       solver=st.one_of(st.none(), st.sampled_from(["euler", "rkf45", "ab6", "nystrom5"]), value_text),
       assignments=st.lists(mostly(extreme_assignments, st.tuples(variable_names, value_text)), max_size=3),
       fmu=mostly(st.sampled_from(["SimplePendulum", "KapitzaPendulum", "Chain5"]),
                  st.sampled_from(["Spring", "NoSuchFmu", "x.fmu", ""])))
@hostile(150)
def test_simulate_arguments(workspace, stop, step, h, solver, assignments, fmu):
    out = workspace / f"simulate{next(counter)}.csv"
    argv = ["simulate", fmu, f"--stop={stop}", f"--step={step}", "--out", str(out)]
    argv += [f"--h={h}"] if h is not None else []
    argv += [f"--solver={solver}"] if solver is not None else []
    for name, value in assignments:
        argv += ["--set", f"{name}={value}"]
    output_checked(cli(argv, workspace), out)


def valid_positive(text: str) -> bool:
    try:
        return math.isfinite(float(text)) and float(text) > 0
    except ValueError:
        return False


def valid_count(largest: int):
    def valid(text: str) -> bool:
        try:
            return 1 <= int(text) <= largest
        except ValueError:
            return False
    return valid


# option -> (commands taking it, what a valid value is)
NUMERIC_OPTIONS = {"--stop": (("simulate", "run"), valid_positive), "--step": (("simulate", "run"), valid_positive),
                   "--h": (("simulate",), valid_positive), "--iterate": (("run",), valid_positive),
                   "--tolerance": (("run", "plan"), valid_positive), "--pixels": (("plan",), valid_positive),
                   "--duration": (("plan", "demo"), valid_positive), "--repeats": (("chart",), valid_count(1000)),
                   "--workers": (("chart", "plan"), valid_count(256))}


@given(option=st.sampled_from(sorted(NUMERIC_OPTIONS)), choice=st.integers(0, 1),
       value=st.one_of(number_text, st.sampled_from(["0", "-3", "1001", "257", "1e9", "/", "."])))
@hostile(80)
def test_option_values_are_checked_before_any_work(workspace, option, choice, value):
    """Every numeric option value that cannot be right is refused by the parser: exit 2, one line
    naming the option, before any work starts."""
    commands, valid = NUMERIC_OPTIONS[option]
    assume(not valid(value))
    command = commands[choice % len(commands)]
    first = {"chart": ["coupling"], "run": [str(SCENE)], "plan": [str(SCENE)], "simulate": ["SimplePendulum"]}
    argv = [command, *first.get(command, []), f"{option}={value}", "--out", str(workspace / f"opt{next(counter)}")]
    outcome = cli(argv, workspace)
    assert outcome.code == 2 and f"argument {option}" in outcome.stderr, outcome


def test_unknown_commands_and_options(workspace):
    for argv in (["nothing"], ["simulate", "SimplePendulum", "--bogus", "1"], ["run"], []):
        outcome = cli(argv, workspace)
        assert outcome.code == 2, outcome


# ---- scene files ------------------------------------------------------------------------------

json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-2**70, 2**70), st.sampled_from([10**400, -10**309, 10**4000]),
              st.floats(allow_nan=True, allow_infinity=True),
              st.text(max_size=8), st.sampled_from(["SimplePendulum", "Spring", "left.x", "rk4", "a,b", "x\ny"])),
    lambda children: st.one_of(st.lists(children, max_size=3), st.dictionaries(st.text(max_size=6), children,
                                                                                max_size=3)),
    max_leaves=8)

# Where a scene file's values live: a path of keys into the valid scene.
SCENE_PLACES = [(), ("name",), ("stop",), ("step",), ("components",), ("components", "left"),
                ("components", "left", "fmu"), ("components", "left", "start"), ("components", "left", "start", "phi"),
                ("components", "left", "start", "solver"), ("components", "left", "traces"),
                ("components", "spring", "start", "k"), ("connections",), ("connections", 0), ("connections", 0, 1),
                ("accuracy",), ("accuracy", "pixels"), ("camera",), ("camera", "scale"), ("camera", "frame_rate"),
                ("components", "left", "extra"), ("extra",)]


def replaced(document, place: tuple, value):
    if not place:
        return value
    head, rest = place[0], place[1:]
    if isinstance(document, dict):
        copy = dict(document)
        copy[head] = replaced(document.get(head, {}), rest, value)
        return copy
    copy = list(document)
    copy[head] = replaced(copy[head], rest, value)
    return copy


def run_scene(workspace: Path, text: str | bytes, extra: list[str] = ()) -> None:
    index = next(counter)
    scene = workspace / f"scene{index}.json"
    scene.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass"))
    out = workspace / f"scene{index}.csv"
    outcome = cli(["run", str(scene), "--stop", "0.05", "--step", "0.01", "--out", str(out), "--quiet", *extra],
                  workspace)
    output_checked(outcome, out)


@given(place=st.sampled_from(SCENE_PLACES), value=json_values)
@hostile(150)
def test_scene_files_with_a_wrong_value(workspace, place, value):
    scene = json.loads(SCENE.read_text())
    scene["camera"] = {"scale": 200, "frame_rate": 25}
    run_scene(workspace, json.dumps(replaced(scene, place, value)))


@given(data=st.one_of(st.binary(max_size=200), st.text(max_size=200).map(str.encode)),
       cut=st.integers(0, 2000), depth=st.integers(0, 200_000))
@hostile(60)
def test_scene_files_that_are_not_json(workspace, data, cut, depth):
    text = SCENE.read_bytes()
    for content in (data, text[:cut], b"[" * depth, text[:cut] + data):
        run_scene(workspace, content)


@given(stop=number_text, step=number_text)
@hostile(40)
def test_scene_times(workspace, stop, step):
    """A scene's own stop and step (no --stop/--step): only short runs or a refusal."""
    scene = json.loads(SCENE.read_text())
    for key, text in (("stop", stop), ("step", step)):
        try:
            scene[key] = float(text) if text.strip().lower() not in ("nan", "inf", "-inf") else text
        except ValueError:
            scene[key] = text
    assume(not (isinstance(scene["stop"], float) and isinstance(scene["step"], float)
                and 0 < scene["step"] and scene["stop"] / scene["step"] > 2000 and scene["stop"] < 1e9))
    index = next(counter)
    path = workspace / f"times{index}.json"
    path.write_text(json.dumps(scene))
    out = workspace / f"times{index}.csv"
    output_checked(cli(["run", str(path), "--out", str(out), "--quiet"], workspace), out)


@given(names=st.lists(st.text(min_size=0, max_size=6), min_size=2, max_size=2),
       twice=st.booleans())
@hostile(40)
def test_component_names_and_double_connections(workspace, names, twice):
    components = {names[0]: {"fmu": "SimplePendulum"}, names[1]: {"fmu": "SimplePendulum"}}
    connections = [[f"{names[0]}.x", f"{names[1]}.F_x"]] + ([[f"{names[0]}.y", f"{names[1]}.F_x"]] if twice else [])
    run_scene(workspace, json.dumps({"components": components, "connections": connections}))


def test_an_input_fed_twice_is_refused(workspace):
    components = {"a": {"fmu": "SimplePendulum"}, "b": {"fmu": "SimplePendulum"}}
    scene = workspace / "twice.json"
    scene.write_text(json.dumps({"components": components, "connections": [["a.x", "b.F_x"], ["a.y", "b.F_x"]]}))
    outcome = cli(["run", str(scene), "--stop", "0.1", "--step", "0.05", "--out", str(workspace / "t.csv")], workspace)
    assert outcome.code == 2 and "input b.F_x is fed by two connections (a.x and a.y)" in outcome.stderr, outcome


# ---- SSD files and archives -------------------------------------------------------------------

def ssp_folder() -> Path:
    return build_dir() / "scenes" / "coupled_pendulums"


SSD_ATTRIBUTES = re.compile(r'(stopTime|stepSize|value|name|source|startElement|endConnector)="([^"]*)"')
ssd_values = st.one_of(st.sampled_from(["INF", "-INF", "NaN", "-1", "0", "1e308", "abc", "", "a,b", "x.y",
                                        "/etc/passwd", "../Spring.fmu", "resources/../../x.fmu", "C:\\x.fmu",
                                        "resources/Spring.fmu", "left", "spring", "F_x", "4294967301", "a" * 300]),
                       st.text(alphabet=st.characters(blacklist_characters='"<&', blacklist_categories=("Cs",)),
                               max_size=10))


@given(edits=st.lists(st.tuples(st.integers(0, 200), ssd_values), min_size=1, max_size=3),
       packed=st.booleans())
@hostile(80)
def test_ssd_files_with_wrong_values(workspace, edits, packed):
    text = (ssp_folder() / "SystemStructure.ssd").read_text()
    matches = list(SSD_ATTRIBUTES.finditer(text))
    for position, value in edits:
        match = matches[position % len(matches)]
        text = text[:match.start(2)] + value + text[match.end(2):]
        matches = list(SSD_ATTRIBUTES.finditer(text))
    index = next(counter)
    folder = workspace / f"ssd{index}"
    shutil.copytree(ssp_folder(), folder)
    (folder / "SystemStructure.ssd").write_text(text)
    target = folder
    if packed:
        target = Path(shutil.make_archive(str(workspace / f"ssd{index}"), "zip", folder)).rename(
            workspace / f"ssd{index}.ssp")
    out = workspace / f"ssd{index}.csv"
    output_checked(cli(["run", str(target), "--stop", "0.05", "--step", "0.01", "--out", str(out), "--quiet"],
                       workspace), out)


def test_an_ssp_cannot_load_an_fmu_from_outside(workspace):
    text = (ssp_folder() / "SystemStructure.ssd").read_text()
    outside = str(build_dir() / "fmus" / "Spring.fmu")
    target = workspace / "outside.ssp"
    with zipfile.ZipFile(target, "w") as archive:
        archive.writestr("SystemStructure.ssd", text.replace('source="resources/Spring.fmu"', f'source="{outside}"'))
        archive.write(ssp_folder() / "resources" / "SimplePendulum.fmu", "resources/SimplePendulum.fmu")
    outcome = cli(["run", str(target), "--stop", "0.1", "--step", "0.05", "--out", str(workspace / "o.csv")], workspace)
    assert outcome.code == 2 and "is absolute; an .ssp loads its FMUs from inside the archive" in outcome.stderr, \
        outcome


# Archive damage: a member added under a hostile name, encrypted, with an unsupported compression
# method, or random bytes of the archive changed or cut off.
member_names = st.one_of(st.sampled_from(["../evil", "/abs", "C:/x", "a\\b", "binaries/linux64/../../up",
                                          "x" * 300, "a/" * 600, "ok/\x01name", "resources/ok.txt"]),
                         st.text(max_size=20))


def rebuilt(source: Path, target: Path, extra_name: str | None = None, method: int | None = None,
            encrypted: str | None = None) -> Path:
    with zipfile.ZipFile(source) as original, zipfile.ZipFile(target, "w") as copy:
        for item in original.infolist():
            data = original.read(item)
            info = zipfile.ZipInfo(item.filename, item.date_time)
            info.compress_type = method if method is not None else item.compress_type
            copy.writestr(info, data)
        if extra_name is not None:
            copy.writestr(zipfile.ZipInfo(extra_name), b"x")
    if encrypted is not None:
        mark_encrypted(target, encrypted)
    return target


def mark_encrypted(path: Path, member: str) -> None:
    """Sets the 'encrypted' flag of one member in its local header and its central directory entry
    (zipfile cannot write encrypted members)."""
    data = bytearray(path.read_bytes())
    with zipfile.ZipFile(path) as archive:
        offset = archive.getinfo(member).header_offset
    data[offset + 6] |= 0x1
    entry = data.find(b"PK\x01\x02")
    while entry != -1:
        name_length = int.from_bytes(data[entry + 28:entry + 30], "little")
        if data[entry + 46:entry + 46 + name_length] == member.encode():
            data[entry + 8] |= 0x1
        entry = data.find(b"PK\x01\x02", entry + 4)
    path.write_bytes(bytes(data))


def damaged(source: Path, target: Path, flips: list[tuple[int, int]], cut: int | None) -> Path:
    data = bytearray(source.read_bytes())
    for position, value in flips:
        data[position % len(data)] = value
    target.write_bytes(bytes(data[:cut] if cut is not None else data))
    return target


def run_archive(workspace: Path, path: Path) -> Outcome:
    out = path.with_suffix(".csv")
    argv = (["simulate", str(path), "--stop", "0.05", "--out", str(out)] if path.suffix == ".fmu" else
            ["run", str(path), "--stop", "0.05", "--step", "0.01", "--out", str(out), "--quiet"])
    outcome = cli(argv, workspace)
    output_checked(outcome, out)
    return outcome


@given(kind=st.sampled_from([".fmu", ".ssp"]), name=member_names)
@hostile(50)
def test_archives_with_a_hostile_member_name(workspace, kind, name):
    source = build_dir() / "fmus" / "SimplePendulum.fmu" if kind == ".fmu" else \
        build_dir() / "scenes" / "coupled_pendulums.ssp"
    with contextlib.suppress(ValueError):  # zipfile itself refuses some names (NUL)
        run_archive(workspace, rebuilt(source, workspace / f"name{next(counter)}{kind}", extra_name=name))


@pytest.mark.parametrize("kind", [".fmu", ".ssp"])
@pytest.mark.parametrize("damage", ["encrypted", "bzip2", "lzma", "long name", "colon", "backslash"])
def test_archive_damage_is_one_line(workspace, kind, damage):
    source = build_dir() / "fmus" / "SimplePendulum.fmu" if kind == ".fmu" else \
        build_dir() / "scenes" / "coupled_pendulums.ssp"
    member = "modelDescription.xml" if kind == ".fmu" else "SystemStructure.ssd"
    target = workspace / f"{damage.replace(' ', '_')}{kind}"
    words = {"encrypted": "is encrypted", "bzip2": "uses compression method 12", "lzma": "uses compression method 14",
             "long name": "is longer than 1024 characters", "colon": "contains a drive or device letter",
             "backslash": "contains a backslash"}[damage]
    if damage in ("encrypted", "bzip2", "lzma"):
        rebuilt(source, target, encrypted=member if damage == "encrypted" else None,
                method={"bzip2": zipfile.ZIP_BZIP2, "lzma": zipfile.ZIP_LZMA}.get(damage))
    else:
        name = {"long name": "resources/" + "x/" * 600 + "y", "colon": "resources/c:x", "backslash": "resources/a\\b"}
        rebuilt(source, target, extra_name=name[damage])
        if kind == ".ssp":  # an unused member of an .ssp is not extracted, so not refused either
            outcome = run_archive(workspace, target)
            assert outcome.code == 0, outcome
            return
    outcome = run_archive(workspace, target)
    assert outcome.code == 2 and words in outcome.stderr, outcome


@given(kind=st.sampled_from([".fmu", ".ssp"]), flips=st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255)),
                                                              max_size=4),
       cut=st.one_of(st.none(), st.integers(0, 200_000)))
@hostile(80)
def test_corrupt_archives(workspace, kind, flips, cut):
    source = build_dir() / "fmus" / "SimplePendulum.fmu" if kind == ".fmu" else \
        build_dir() / "scenes" / "coupled_pendulums.ssp"
    run_archive(workspace, damaged(source, workspace / f"corrupt{next(counter)}{kind}", flips, cut))


def test_extraction_is_bounded(workspace, monkeypatch):
    """Past the bounds on size and member count: a clear error, nothing left; a large member the
    importer does not need is not extracted at all."""
    source = build_dir() / "fmus" / "SimplePendulum.fmu"
    big = workspace / "big.fmu"
    with zipfile.ZipFile(source) as original, zipfile.ZipFile(big, "w", zipfile.ZIP_DEFLATED) as copy:
        for item in original.infolist():
            copy.writestr(item, original.read(item))
        copy.writestr("documentation/zeros.bin", bytes(200 << 20))  # 200 MB of zeros, 0.2 MB compressed
    folder = archives.extract_fmu(big)
    try:
        assert not (folder / "documentation").exists()
        assert sum(p.stat().st_size for p in folder.rglob("*") if p.is_file()) < 1 << 20
    finally:
        shutil.rmtree(folder)
    monkeypatch.setattr(archives, "MAX_BYTES", 10_000)
    outcome = cli(["simulate", str(source), "--stop", "0.1", "--out", str(workspace / "b.csv")], workspace)
    assert outcome.code == 2 and "more than 10000 bytes to extract (the bound)" in outcome.stderr, outcome
    monkeypatch.setattr(archives, "MAX_MEMBERS", 3)
    outcome = cli(["simulate", str(source), "--stop", "0.1", "--out", str(workspace / "b.csv")], workspace)
    assert outcome.code == 2 and "more than the 3 allowed" in outcome.stderr, outcome


# ---- outputs ----------------------------------------------------------------------------------

def test_output_paths(workspace):
    (workspace / "a_file").write_text("keep me")
    cases = [(["simulate", "SimplePendulum", "--stop", "0.1", "--out", str(workspace)], "is a folder, not a file"),
             (["simulate", "SimplePendulum", "--stop", "0.1", "--out", str(workspace / "a_file" / "x.csv")],
              "is a file, not a folder"),
             (["demo", "--out", str(workspace / "a_file")], "is a file, not a folder"),
             (["chart", "coupling", "--out", str(workspace / "a_file")], "is a file, not a folder"),
             (["run", str(SCENE), "--out", str(SCENE)], "is this command's input"),
             (["simulate", "SimplePendulum", "--stop", "0.1", "--out", "/dev/null"], "is not a regular file"),
             (["simulate", "SimplePendulum", "--stop", "0.1", "--out", str(build_dir() / "fmus" / "Spring.fmu")],
              "is an existing .fmu input file")]
    for argv, words in cases:
        outcome = cli(argv, workspace)
        assert outcome.code == 2 and words in outcome.stderr, outcome
    assert (workspace / "a_file").read_text() == "keep me"


def test_every_output_makes_its_missing_folders(workspace):
    """One rule for every output path: folders that do not exist yet are made (a parent that is a file is
    refused, above), for a table, a picture, a reference table and an archive alike."""
    def at(path: str) -> str:
        return str(workspace / "made" / path)
    cases = [(["simulate", "SimplePendulum", "--stop", "0.05", "--out", at("n1/a/x.csv")], ["n1/a/x.csv"]),
             (["simulate", "SimplePendulum", "--stop", "0.05", "--out", at("x.csv"), "--plot", at("n2/b/x.png")],
              ["n2/b/x.png"]),
             (["run", str(SCENE), "--stop", "0.05", "--out", at("n3/c/x.csv"), "--reference", at("n4/d/r.csv")],
              ["n3/c/x.csv", "n4/d/r.csv"]),
             (["export", str(SCENE), "--ssp", at("n5/e/x.ssp")], ["n5/e/x.ssp"])]
    for argv, made in cases:
        outcome = cli(argv, workspace)
        assert outcome.code == 0, outcome
        assert all(Path(at(path)).is_file() for path in made), (argv, outcome)


def test_a_failed_run_leaves_an_earlier_result_alone(workspace):
    out = workspace / "earlier.csv"
    assert cli(["simulate", "SimplePendulum", "--stop", "0.1", "--out", str(out)], workspace).code == 0
    before = out.read_text()
    outcome = cli(["simulate", "SimplePendulum", "--stop", "0.1", "--set", "L=-1", "--out", str(out)], workspace)
    assert outcome.code == 2 and out.read_text() == before, outcome


def test_a_short_run_keeps_its_start(workspace):
    """--stop shorter than --step: the t = 0 row and the stop row, each labelled with its own time."""
    out = workspace / "short.csv"
    assert cli(["simulate", "SimplePendulum", "--stop", "1e-12", "--step", "0.01", "--out", str(out)],
               workspace).code == 0
    times = [float(line.split(",")[0]) for line in out.read_text().splitlines()[1:]]
    assert times == [0.0, 1e-12]


# ---- SSP features the harness does not carry out, and files it must not read -----------------

# as the exporter writes it (ElementTree puts a space before "/>")
FIRST_CONNECTION = '<ssd:Connection startElement="left" startConnector="x" endElement="spring" endConnector="a_x" />'
FIRST_VALUES_END = "</ssd:ParameterValues>"
SSM = "http://ssp-standard.org/SSP1/SystemStructureParameterMapping"
SSD_EDITS = {
    "linear transformation": (FIRST_CONNECTION, FIRST_CONNECTION[:-2] + '><ssc:LinearTransformation factor="2"/>'
                              "</ssd:Connection>", "has a LinearTransformation, which is not supported"),
    "parameter mapping": (FIRST_VALUES_END, FIRST_VALUES_END + f'<ssd:ParameterMapping><ssm:ParameterMapping '
                          f'xmlns:ssm="{SSM}" version="1.0"><ssm:MappingEntry source="a" target="k"/>'
                          "</ssm:ParameterMapping></ssd:ParameterMapping>", "ParameterMapping, which is not supported"),
    "nested system": ("</ssd:Elements>", '<ssd:System name="inner"/></ssd:Elements>',
                      "only FMU components are supported"),
    "binding of no component": ("<ssd:Elements>", '<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
                                '<ssv:ParameterSet version="1.0" name="s"><ssv:Parameters>'
                                '<ssv:Parameter name="ghost.k">'
                                '<ssv:Real value="1"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>'
                                "</ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings><ssd:Elements>",
                                "system parameter 'ghost.k' names no component's variable"),
    "parameter without a name": ('<ssv:Parameter name="k">', "<ssv:Parameter>", "a parameter without a name"),
    "system connector": (FIRST_CONNECTION, FIRST_CONNECTION.replace('startElement="left" ', ""),
                         "joins a connector of the system itself"),
}


@pytest.mark.parametrize("edit", sorted(SSD_EDITS))
@pytest.mark.parametrize("packed", [False, True])
def test_unsupported_ssp_features_are_refused(workspace, edit, packed):
    """Each edit is valid SSP 1.0; each is refused by name, never ignored."""
    old, new, words = SSD_EDITS[edit]
    text = (ssp_folder() / "SystemStructure.ssd").read_text()
    assert old in text
    index = next(counter)
    folder = workspace / f"feature{index}"
    shutil.copytree(ssp_folder(), folder)
    (folder / "SystemStructure.ssd").write_text(text.replace(old, new, 1))
    target = folder
    if packed:
        target = Path(shutil.make_archive(str(folder), "zip", folder)).rename(folder.with_suffix(".ssp"))
    outcome = cli(["run", str(target), "--stop", "0.05", "--step", "0.01", "--out", str(workspace / "f.csv"),
                   "--quiet"], workspace)
    assert outcome.code == 2 and words in outcome.stderr, outcome


@pytest.mark.timeout(60)  # a pipe that is opened blocks: this bound turns a regression into a failure
def test_only_regular_files_are_read(workspace):
    """A pipe among the folder's .ssv files is not opened unless the SSD names one; a named one, or
    a scene file that is a pipe, is refused."""
    import os
    folder = workspace / f"pipes{next(counter)}"
    shutil.copytree(ssp_folder(), folder)
    os.mkfifo(folder / "resources" / "stray.ssv")
    args = ["--stop", "0.05", "--step", "0.01", "--out", str(workspace / "p.csv"), "--quiet"]
    assert cli(["run", str(folder), *args], workspace).code == 0
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace("<ssd:ParameterBindings>", '<ssd:ParameterBindings><ssd:ParameterBinding '
                                          'source="resources/stray.ssv"/>', 1))
    outcome = cli(["run", str(folder), *args], workspace)
    assert outcome.code == 2 and "'resources/stray.ssv': not found or not a regular file" in outcome.stderr, outcome
    os.mkfifo(workspace / "pipe.json")
    outcome = cli(["run", str(workspace / "pipe.json"), *args], workspace)
    assert outcome.code == 2 and "is not a regular file or a folder" in outcome.stderr, outcome


# ---- outputs and the files of an input folder ---------------------------------------------------

def test_outputs_never_replace_an_input(workspace):
    folder = workspace / f"inputs{next(counter)}"
    shutil.copytree(ssp_folder(), folder)
    (folder / "notes.txt").write_text("mine")
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    for target in (folder / "notes.txt", folder / "resources" / "Spring.fmu", folder / "SystemStructure.ssd"):
        outcome = cli(["run", str(folder), "--stop", "0.05", "--step", "0.01", "--out", str(target), "--quiet"],
                      workspace)
        assert outcome.code == 2 and str(target) in outcome.stderr, outcome
    assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before
    fresh = folder / "result.csv"  # a new file beside the inputs is fine
    assert cli(["run", str(folder), "--stop", "0.05", "--step", "0.01", "--out", str(fresh), "--quiet"],
               workspace).code == 0
    simulate = ["simulate", "SimplePendulum", "--stop", "0.05", "--out", str(workspace / "same.png")]
    outcome = cli([*simulate, "--plot", str(workspace / "same.png")], workspace)
    assert outcome.code == 2 and "is already the --out file" in outcome.stderr, outcome
    outcome = cli([*simulate, "--plot", str(workspace / "trace.csv")], workspace)
    assert outcome.code == 2 and "must end in .png, .svg, .pdf" in outcome.stderr, outcome


def test_outputs_are_plain_files_through_links(workspace):
    """Written with the permissions open() would give, through a symbolic link (the link stays), and
    under a name as long as the file system allows."""
    import os
    import stat
    target = workspace / "linked_target.csv"
    target.write_text("old")
    link = workspace / "link.csv"
    link.symlink_to(target.name)
    plot = workspace / "trace.svg"
    assert cli(["simulate", "SimplePendulum", "--stop", "0.05", "--out", str(link), "--plot", str(plot)],
               workspace).code == 0
    assert link.is_symlink() and well_formed_csv(target) == 6
    assert plot.read_bytes().lstrip().startswith(b"<?xml")
    mask = os.umask(0)
    os.umask(mask)
    for path in (target, plot):
        assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~mask, oct(path.stat().st_mode)
    long_name = workspace / ("n" * 251 + ".csv")
    assert cli(["simulate", "SimplePendulum", "--stop", "0.05", "--out", str(long_name)], workspace).code == 0
    assert well_formed_csv(long_name) == 6


# ---- values valid in form that the harness could not carry out ------------------------------------

def scene_with(workspace: Path, change) -> Path:
    scene = json.loads((PROJECT_ROOT / "scenes" / "thesis_scene.json").read_text())
    change(scene)
    path = workspace / f"thesis{next(counter)}.json"
    path.write_text(json.dumps(scene))
    return path


@pytest.mark.parametrize("change,words", [
    (lambda s: s.update(stop=int("9" * 400)), '"stop" = inf must be a positive finite number'),
    (lambda s: s["components"]["simple"]["start"].update(phi=-int("9" * 400)), "'phi' = -inf is not a finite number"),
    (lambda s: s["components"]["simple"]["start"].update(phi="0.5"), "'phi' = \"0.5\" is a string: write a number"),
    (lambda s: s["components"]["simple"]["start"].update(phi="1_000"), "phi = '1_000' is not a number"),
    (lambda s: s["components"]["simple"]["start"].update(phi="\u0967"), "phi = '\u0967' is not a number"),
    (lambda s: s["components"]["simple"].update(traces=[["nope", "y"]]),
     "a trace names 'nope', which is not an output"),
    (lambda s: s["camera"].update(frame_rate=1e300), "frames; lower the camera's frame rate"),
    (lambda s: s["camera"].update(frame_rate=1e-300), "is longer than the 0.2 s planned")])
def test_plans_of_scenes_that_cannot_be_carried_out(workspace, change, words):
    outcome = cli(["plan", str(scene_with(workspace, change)), "--duration", "0.2", "--workers", "1"], workspace)
    assert outcome.code == 2 and words in outcome.stderr, outcome


def test_a_table_too_large_to_hold_is_refused(workspace):
    outcome = cli(["simulate", "DoublePendulum", "--stop", "1e5", "--step", "0.01", "--out", str(workspace / "t.csv")],
                  workspace)
    assert outcome.code == 2 and "more than the 1e+08 allowed" in outcome.stderr, outcome


def test_an_atlas_of_objects_without_a_linear_model(workspace):
    outcome = cli(["chart", "stability", "--objects", "KapitzaPendulum", "--quick", "--out",
                   str(workspace / "atlas")], workspace)
    assert outcome.code == 2 and "no linear model to measure a stability limit on" in outcome.stderr, outcome


# ---- FMUs whose binary or names would break the harness -------------------------------------------

def edited_fmu(source: Path, target: Path, edit) -> Path:
    """A copy of the FMU with edit(name, data) -> data applied to each member."""
    with zipfile.ZipFile(source) as original, zipfile.ZipFile(target, "w") as copy:
        for item in original.infolist():
            copy.writestr(item, edit(item.filename, original.read(item)))
    return target


@pytest.mark.parametrize("edit,words", [
    (lambda name, data: data[:20000] if name.endswith(".so") else data, "is truncated (20000 bytes"),
    (lambda name, data: data[:40] if name.endswith(".so") else data, "is not an ELF shared library"),
    (lambda name, data: data.replace(b'modelIdentifier="SimplePendulum"', b'modelIdentifier="../../x"'),
     "modelIdentifier '../../x' is not a C identifier")])
def test_binaries_that_cannot_be_loaded_safely(workspace, fmu_paths, edit, words):
    """A truncated library would be a bus error at load (the process killed, its temporary folders left)."""
    fmu = edited_fmu(fmu_paths["SimplePendulum"], workspace / f"bad{next(counter)}.fmu", edit)
    outcome = cli(["simulate", str(fmu), "--stop", "0.05", "--out", str(workspace / "b.csv")], workspace)
    assert outcome.code == 2 and words in outcome.stderr, outcome


def test_structured_variable_names_keep_the_csv_in_shape(workspace, fmu_paths):
    """FMI allows any text as a name (a[1,2] in structured naming); the header quotes it as RFC 4180 says."""
    import csv
    names = {b'name="x"': 'a[1,2]', b'name="y"': 'say "y"', b'name="v_x"': "two\nlines"}

    def rename(member: str, data: bytes) -> bytes:
        if member == "modelDescription.xml":
            for old, new in names.items():
                data = data.replace(old, b'name="' + new.replace('"', "&quot;").replace("\n", "&#10;").encode() + b'"')
        return data
    fmu = edited_fmu(fmu_paths["SimplePendulum"], workspace / "structured.fmu", rename)
    out = workspace / "structured.csv"
    assert cli(["simulate", str(fmu), "--stop", "0.05", "--out", str(out)], workspace).code == 0
    with out.open(newline="") as stream:
        rows = list(csv.reader(stream))
    assert set(names.values()) <= set(rows[0]) and all(len(row) == len(rows[0]) for row in rows[1:])
    assert len(rows) == 7 and all(math.isfinite(float(cell)) for row in rows[1:] for cell in row)


# ---- the second review: loops, text no file can name, object files, derived outputs ----------------

def test_symbolic_link_loops_are_one_line(workspace):
    loop = workspace / "loop"
    if not loop.is_symlink():
        loop.symlink_to("loop")
    for argv in (["simulate", "SimplePendulum", "--stop", "0.05", "--out", str(loop)],
                 ["simulate", str(loop), "--out", str(workspace / "l.csv")],
                 ["run", str(loop), "--out", str(workspace / "l.csv")]):
        assert cli(argv, workspace).code == 2


@pytest.mark.parametrize("text,words", [
    ('{"components": {"c": {"fmu": "a\\u0000b"}}}', "holds a NUL or an unpaired surrogate"),
    ('{"name": "\\udfff", "components": {"c": {"fmu": "SimplePendulum"}}}', "holds a NUL or an unpaired surrogate"),
    ('{"components": {"c": {"fmu": "SimplePendulum", "traces": []}}}', '"traces" is empty')])
def test_scene_text_no_file_or_terminal_can_take(workspace, text, words):
    path = workspace / f"text{next(counter)}.json"
    path.write_text(text)
    outcome = cli(["run", str(path), "--stop", "0.05", "--step", "0.01", "--out", str(workspace / "t.csv")], workspace)
    assert outcome.code == 2 and words in outcome.stderr, outcome


def test_an_ssd_files_folder_is_an_input_too(workspace):
    folder = workspace / f"ssdfolder{next(counter)}"
    shutil.copytree(ssp_folder(), folder)
    (folder / "params.ssv").write_text("keep")
    outcome = cli(["run", str(folder / "SystemStructure.ssd"), "--stop", "0.05", "--step", "0.01", "--out",
                   str(folder / "params.ssv")], workspace)
    assert outcome.code == 2 and "input folder" in outcome.stderr and (folder / "params.ssv").read_text() == "keep"


def test_fixed_output_names_are_written_through_links_and_never_over_pipes(workspace):
    import os
    out = workspace / f"derived{next(counter)}"
    out.mkdir()
    target = workspace / "elsewhere.fmu"
    (out / "SimplePendulum.fmu").symlink_to(target)
    source = PROJECT_ROOT / "modelDescription" / "SimplePendulum.toml"
    assert cli(["derive", str(source), "--out", str(out)], workspace).code == 0
    assert (out / "SimplePendulum.fmu").is_symlink() and zipfile.is_zipfile(target)
    (out / "SimplePendulum.fmu").unlink()
    os.mkfifo(out / "SimplePendulum.fmu")
    outcome = cli(["derive", str(source), "--out", str(out)], workspace)
    assert outcome.code == 2 and "is not a regular file" in outcome.stderr, outcome
    (out / "SimplePendulum.fmu").unlink()
    (out / "SimplePendulum.fmu").mkdir()
    outcome = cli(["derive", str(source), "--out", str(out)], workspace)
    assert outcome.code == 2 and "is a folder, not a file" in outcome.stderr, outcome


@pytest.mark.parametrize("old,new,words", [
    ('U = "-m*g*L*cos(phi)"', 'U = "-m*g*L*cos(phi)*10**1000000"', "a power of numbers beyond double precision"),
    ('U = "-m*g*L*cos(phi)"', 'U = "-m*g*L*cos(phi) + 0*9**9**9**9"', "needs a plain number as its exponent"),
    ('U = "-m*g*L*cos(phi)"', 'U = "-m*g*L*cos(phi)*1e400"', "a number beyond double precision"),
    ('U = "-m*g*L*cos(phi)"', 'U = "sqrt(-1 - phi**2)"', "not a finite real number at the start values"),
    ('L = { start = 1.0,', 'L = { start = 1' + "0" * 400 + ',', "must be a finite number, not a number of 401 digits")])
def test_object_files_with_numbers_no_double_holds(workspace, old, new, words):
    text = (PROJECT_ROOT / "modelDescription" / "SimplePendulum.toml").read_text()
    assert old in text
    path = workspace / f"object{next(counter)}.toml"
    path.write_text(text.replace(old, new, 1))
    outcome = cli(["derive", str(path), "--out", str(workspace / "objects")], workspace)
    assert outcome.code == 2 and words in outcome.stderr, outcome


@pytest.mark.timeout(60)
def test_an_object_file_that_is_a_pipe(workspace):
    import os
    os.mkfifo(workspace / "pipe.toml")
    outcome = cli(["derive", str(workspace / "pipe.toml"), "--out", str(workspace / "objects")], workspace)
    assert outcome.code == 2 and "is not a regular file" in outcome.stderr, outcome


def test_an_fmu_that_does_not_match_its_object_file(workspace, fmu_paths):
    fmu = edited_fmu(fmu_paths["SimplePendulum"], workspace / "renamed.fmu",
                     lambda name, data: data.replace(b'name="x"', b'name="xx"') if name == "modelDescription.xml"
                     else data)
    scene = workspace / "renamed.json"
    scene.write_text(json.dumps({"stop": 1, "step": 0.01, "accuracy": {"position": 0.01},
                                 "components": {"p": {"fmu": str(fmu)}}}))
    outcome = cli(["plan", str(scene), "--workers", "1"], workspace)
    assert outcome.code == 2 and "lacks 'x', which its object file" in outcome.stderr, outcome


def test_a_coupled_plan_whose_reference_cannot_be_computed(workspace):
    def stiff(scene):
        scene["components"]["spring"]["start"]["k"] = 1e300
    scene = json.loads(SCENE.read_text())
    stiff(scene)
    path = workspace / "stiff.json"
    path.write_text(json.dumps(scene))
    outcome = cli(["plan", str(path), "--tolerance", "0.001", "--workers", "1"], workspace)
    assert outcome.code == 2 and "the monolithic reference could not be computed" in outcome.stderr \
        and "stiff or the motion blows up" in outcome.stderr, outcome


@pytest.mark.parametrize("command", [["run"], ["plan", "--tolerance", "0.01"]])
def test_an_output_never_replaces_an_fmu_the_scene_names(workspace, command):
    """The scene loads its FMU from a file whose name looks like an output; writing there is refused
    and the FMU stays as it was."""
    fmu = workspace / f"pend{next(counter)}.csv"
    fmu.write_bytes((build_dir() / "fmus" / "SimplePendulum.fmu").read_bytes())
    scene = workspace / f"scene{next(counter)}.json"
    scene.write_text(json.dumps({"name": "s", "stop": 1.0, "step": 0.1, "components": {"p": {"fmu": str(fmu)}},
                                 "connections": []}))
    outcome = cli([command[0], str(scene), *command[1:], "--out", str(fmu)], workspace)
    assert outcome.code == 2 and "is this command's input" in outcome.stderr, outcome
    assert zipfile.is_zipfile(fmu)


# ================ broken input, the command line run as a user runs it: in a process of its own =======================

def harness(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "harness", *args], capture_output=True, text=True)


def one_line_error(result: subprocess.CompletedProcess, words: str, code: int = 2) -> None:
    lines = result.stderr.strip().splitlines()
    assert result.returncode == code, result.stderr
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in result.stderr, result.stderr


def rewrite_fmu(source: Path, target: Path, drop_prefix: str = "", replace: tuple[bytes, bytes] | None = None) -> Path:
    with zipfile.ZipFile(source) as original, zipfile.ZipFile(target, "w") as copy:
        for item in original.infolist():
            if drop_prefix and item.filename.startswith(drop_prefix):
                continue
            data = original.read(item)
            if replace and item.filename == "modelDescription.xml":
                data = data.replace(*replace)
            copy.writestr(item, data)
    return target


@pytest.fixture
def broken(fmu_paths, tmp_path) -> dict[str, Path]:
    simple = fmu_paths["SimplePendulum"]
    (tmp_path / "corrupt.fmu").write_bytes(b"PK\x03\x04 this is not a zip archive")
    return {
        "corrupt": tmp_path / "corrupt.fmu",
        "no binary": rewrite_fmu(simple, tmp_path / "nobinary.fmu", drop_prefix="binaries/"),
        "FMI 3.0": rewrite_fmu(simple, tmp_path / "fmi3.fmu", replace=(b'fmiVersion="2.0"', b'fmiVersion="3.0"')),
        "missing": tmp_path / "missing.fmu",
    }


@pytest.mark.parametrize("case,words", [("corrupt", "not a zip archive"),
                                        ("no binary", "no binary for this platform"),
                                        ("FMI 3.0", "Failed to validate modelDescription.xml: (line 5, column 0): "
                                                    "Element 'fmiModelDescription', attribute 'guid': "
                                                    "The attribute 'guid' is not allowed; and "),
                                        ("missing", "no such FMU file")])
def test_broken_fmus(broken, tmp_path, case, words):
    one_line_error(harness("simulate", str(broken[case]), "--out", str(tmp_path / "x.csv")), words)
    if case != "missing":
        result = harness("validate", str(broken[case]))
        assert result.returncode == 1 and "FAIL" in result.stdout and "Traceback" not in result.stderr


def ssp_copy(tmp_path: Path) -> Path:
    folder = tmp_path / "ssp"
    shutil.copytree(build_dir() / "scenes" / "coupled_pendulums", folder)
    return folder


def ssd_edited(text: str, pattern: str, replacement: str) -> str:
    """`text` with every match of `pattern` replaced; the pattern must match, or the test would pass
    on an SSD it never edited. Patterns allow for the exporter's line breaks between elements."""
    text, count = re.subn(pattern, replacement, text)
    assert count, pattern
    return text


def test_malformed_ssd(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    (folder / "SystemStructure.ssd").write_text("<ssd:SystemStructureDescription xmlns:ssd='x'><unclosed")
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "malformed SSD")


def test_an_ssd_against_its_schema_names_the_first_problem(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    text = ssd.read_text()
    line = text[:text.index("<ssd:System ")].count("\n") + 1  # where the edit lands, as the schema check counts
    ssd.write_text(text.replace("<ssd:System ", '<ssd:System bogus="1" ', 1))
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   f"Failed to validate SystemStructure.ssd: (line {line}, column 0): Element "
                   "'{http://ssp-standard.org/SSP1/SystemStructureDescription}System', attribute 'bogus': "
                   "The attribute 'bogus' is not allowed)")


def test_ssd_connection_to_a_missing_variable(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('endElement="spring" endConnector="a_x"',
                                           'endElement="spring" endConnector="a_z"'))
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "spring has no input 'a_z'")


def test_ssd_component_without_its_fmu(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    (folder / "resources" / "Spring.fmu").unlink()
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "source resources/Spring.fmu not found")


def test_connection_between_different_units(fmu_paths, tmp_path):
    scene = json.loads((PROJECT_ROOT / "scenes" / "coupled_pendulums.json").read_text())
    scene["connections"][0] = ["left.phi", "spring.a_x"]  # an angle into a position
    del scene["bonds"]  # whose position this connection was
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    one_line_error(harness("run", str(path), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "units differ (rad to m)")


def test_a_stopped_run_keeps_its_rows(fmu_paths, tmp_path):
    scene = json.loads((PROJECT_ROOT / "scenes" / "coupled_pendulums.json").read_text())
    scene["components"]["spring"]["start"]["k"] = 4000.0
    for side in ("left", "right"):
        scene["components"][side]["start"].update(solver="euler", h=0.05)
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / "out.csv"
    result = harness("run", str(path), "--stop", "5", "--step", "0.05", "--out", str(out), "--quiet")
    assert result.returncode == 1 and "could not complete the step" in result.stderr
    rows = out.read_text().splitlines()
    assert rows[0].startswith("time,") and len(rows) > 5


# ---- writing results: checked paths, no loss on failure, interrupts keep rows ------------------

def test_a_full_disk_loses_nothing(fmu_paths, tmp_path, monkeypatch):
    """Writing fails (ENOSPC): one line naming the file, the earlier file as it was, no temporary file."""
    import errno
    from harness import output
    from harness.cli import main
    out = tmp_path / "result.csv"
    out.write_text("earlier result\n")

    class FullDisk(io.StringIO):
        def write(self, text):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def close(self):
            pass

    monkeypatch.setattr(output.os, "fdopen", lambda descriptor, *args, **kwargs: (os.close(descriptor), FullDisk())[1])
    code = main(["simulate", "SimplePendulum", "--stop", "0.1", "--out", str(out)])
    assert code == 2 and out.read_text() == "earlier result\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.csv"]


def test_an_unwritable_folder_is_one_line(fmu_paths, tmp_path, monkeypatch, capsys):
    """A folder the user may not write to (simulated: root may write anywhere)."""
    import errno
    from harness import output
    from harness.cli import main

    def refused(*args, **kwargs):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))

    monkeypatch.setattr(output.tempfile, "mkstemp", refused)
    code = main(["simulate", "SimplePendulum", "--stop", "0.1", "--out", str(tmp_path / "x.csv")])
    error = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(error) == 1 and "x.csv: cannot write here (Permission denied)" in error[0], error


def test_two_runs_writing_one_file_do_not_interleave(fmu_paths, tmp_path):
    out = tmp_path / "shared.csv"
    runs = [subprocess.Popen([sys.executable, "-m", "harness", "simulate", "SimplePendulum", "--stop", "20",
                              "--step", "0.001", "--set", f"phi={phi}", "--out", str(out)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) for phi in (0.5, 0.25)]
    assert [run.wait() for run in runs] == [0, 0]
    rows = out.read_text().splitlines()
    assert len(rows) == 20002 and float(rows[1].split(",")[1]) in (0.5, 0.25)
    phi0 = rows[1].split(",")[1]
    assert all(len(row.split(",")) == len(rows[0].split(",")) for row in rows)
    assert not [p for p in tmp_path.iterdir() if p.name != "shared.csv"]
    assert phi0 in ("0.5", "0.25")


@pytest.mark.parametrize("command,signal_number", [("simulate", signal.SIGINT), ("run", signal.SIGTERM)])
def test_an_interrupted_run_keeps_its_rows_and_removes_its_temporary_folders(fmu_paths, tmp_path, command,
                                                                             signal_number):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    out = tmp_path / "long.csv"
    args = (["simulate", "SimplePendulum", "--stop", "2000", "--step", "0.001", "--h", "1e-5"] if command == "simulate"
            else ["run", str(build_dir() / "scenes" / "coupled_pendulums.ssp"), "--stop", "2000", "--step", "0.001",
                  "--quiet"])
    process = subprocess.Popen([sys.executable, "-m", "harness", *args, "--out", str(out)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env={**os.environ, "TMPDIR": str(scratch)},
                               # a shell running the tests in the background ignores SIGINT, and children inherit that
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 60
    while not list(scratch.iterdir()) and time.monotonic() < deadline:  # its FMUs are extracted: it runs
        time.sleep(0.05)
    time.sleep(2.0)
    process.send_signal(signal_number)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130 and stderr.strip() == "harness: interrupted", stderr
    rows = out.read_text().splitlines()
    assert len(rows) > 10 and all(len(r.split(",")) == len(rows[0].split(",")) for r in rows)
    assert list(scratch.iterdir()) == []
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".part")] == []


def handlers_installed(pid: int) -> bool:
    """Whether the harness in process pid has installed its signal handlers (it catches SIGTERM): from
    then on its own code runs, before that only the interpreter's start."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("SigCgt:"):
                return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
    except OSError:
        pass
    return False


def test_an_interrupt_at_any_moment_of_a_rolled_back_run_ends_it_cleanly(fmu_paths, tmp_path):
    """`run --tolerance` on the coupled scene (the Python loop: every macro step saves, restores and
    releases FMU states, and the FMUs call back into the harness) interrupted at 25 seeded random
    moments from the harness's start to past the run's end (loading, extracting and instantiating the
    FMUs, the loop, writing, freeing): each ends with exit code 130 and the one line "harness:
    interrupted" (0 and no line where it had finished), leaves nothing in its temporary folder and no
    .part file, and keeps its rows so far: lines of the uninterrupted run's file, in their order. Before
    the fix an interrupt inside the FMU's memory callbacks (Python, then) corrupted the heap (SIGABRT,
    SIGSEGV) or was swallowed, the run going on to its end deaf to Ctrl-C."""
    import random
    scene = PROJECT_ROOT / "scenes" / "coupled_pendulums.json"
    args = ["run", str(scene), "--tolerance", "1e-3", "--stop", "4", "--quiet"]

    def interrupted(name: str, delay: float | None) -> tuple[subprocess.Popen, str, Path, Path, float]:
        """The run, sent SIGINT `delay` seconds after its handlers are installed; also how long it went on."""
        scratch, out = tmp_path / name / "scratch", tmp_path / name / "out" / "coupled.csv"
        scratch.mkdir(parents=True)
        out.parent.mkdir()
        process = started([*args, "--out", str(out)], scratch)
        deadline = time.monotonic() + 30
        while not handlers_installed(process.pid) and process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.001)
        if delay is not None:
            time.sleep(delay)
            process.send_signal(signal.SIGINT)
        signalled = time.monotonic()
        try:
            _, stderr = process.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
            pytest.fail(f"the run interrupted {delay} s after its start did not end within 60 s")
        return process, stderr, scratch, out, time.monotonic() - signalled

    process, stderr, scratch, out, duration = interrupted("whole", None)
    assert process.returncode == 0 and stderr == "", stderr
    whole = out.read_text().splitlines()
    assert len(whole) == 402 and whole[0].startswith("time,") and list(scratch.iterdir()) == []

    rng = random.Random(20240611)
    outcomes = []
    for k, delay in enumerate(sorted(rng.uniform(0.0, 1.15 * duration) for _ in range(25))):
        process, stderr, scratch, out, went_on = interrupted(f"run{k}", delay)
        where = f"interrupted {delay:.3f} s after its start (the whole run: {duration:.2f} s)"
        lines = stderr.strip().splitlines()
        if process.returncode == 0:  # it was ending: not an interrupt lost, the run going on to its end
            assert stderr == "" and went_on < 1.0, f"{where}: went on for {went_on:.2f} s, stderr {stderr!r}"
        else:
            assert process.returncode == 130 and lines == ["harness: interrupted"], \
                f"{where}: exit code {process.returncode}, stderr {stderr!r}"
        assert list(scratch.rglob("*")) == [], f"{where}: left {sorted(scratch.rglob('*'))}"
        assert [p.name for p in out.parent.iterdir() if p.name != out.name] == [], where
        rows = out.read_text().splitlines() if out.exists() else []
        assert rows == whole[:len(rows)] and len(rows) != 1, f"{where}: {len(rows)} lines, not the run's first ones"
        assert process.returncode == 130 or len(rows) == len(whole), where
        outcomes.append(process.returncode)
    assert outcomes.count(130) >= 10, outcomes  # most moments fall inside the run


def test_no_fmu_state_outlives_its_use_over_a_long_iterated_run(fmu_paths, monkeypatch):
    """100 macro steps, each iterated to 1e-10 (a state saved and restored per pass) under step
    doubling and retry on discard: at every recorded row each component holds exactly what it held
    before the first step (counted through the FMU's memory callbacks), so every state the parts
    saved was released once it had served, and nothing after close."""
    from harness.cosim.master import Master, MasterOptions
    from harness.cosim.system import load_system
    from harness.fmi.fmu_instance import LogCollector
    monkeypatch.setattr(LogCollector, "counting", True)
    with load_system(PROJECT_ROOT / "scenes" / "coupled_pendulums.json") as system:
        master = Master(system, MasterOptions(stop=10.0, step=0.1, iterate_tol=1e-10, tolerance=1e-4,
                                              on_discard="retry"))
        held: list[list[int]] = []
        with master:
            before = [u.instance.log.live_blocks for u in master.units]
            result = master.run(on_row=lambda row: held.append([u.instance.log.live_blocks for u in master.units]))
            assert result.stopped_at is None and len(held) == 101 and result.iterations > 100
            assert result.retries > 0  # step doubling rejected steps: states were restored, not only taken
            assert held == [before] * 101
            assert [u.live_states for u in master.units] == [0] * len(master.units)
        assert [unit.instance.log.live_blocks for unit in master.units] == [0] * len(master.units)


def test_a_discard_inside_an_iterated_step_releases_its_states(fmu_paths, monkeypatch):
    """A step that fails deep inside retry and iteration (every halving discards) leaves no state
    behind: the run stops with its message and the components hold what they held before it."""
    from harness.cosim.master import Master, MasterOptions
    from harness.cosim.system import load_system
    from harness.fmi.fmu_instance import LogCollector
    monkeypatch.setattr(LogCollector, "counting", True)
    with load_system(PROJECT_ROOT / "scenes" / "coupled_pendulums.json") as system:
        # the spring's rest length 0 with both ends at one point is fine; a huge stiffness blows up
        system.components[0].start.update(k=1e9)
        master = Master(system, MasterOptions(stop=1.0, step=0.1, iterate_tol=1e-10, on_discard="retry",
                                              max_halvings=3))
        with master:
            before = [u.instance.log.live_blocks for u in master.units]
            result = master.run()
            assert result.stopped_at is not None and "could not complete" in result.message
            assert [u.live_states for u in master.units] == [0] * len(master.units)
            assert [u.instance.log.live_blocks for u in master.units] == before


def started(args: list[str], scratch: Path, env: dict | None = None) -> subprocess.Popen:
    """The harness in a process of its own, with its temporary files in `scratch`."""
    return subprocess.Popen([sys.executable, "-m", "harness", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "TMPDIR": str(scratch), **(env or {})},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def wait_for(condition, seconds: float = 120) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, "the run never reached the point to interrupt"
        time.sleep(0.05)


def processes_naming(text: str) -> list[str]:
    """Command lines of the running processes that mention text (a folder only our run uses)."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            line = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if entry.name.isdigit() and text in line:
            found.append(line)
    return found


def ended_cleanly(process: subprocess.Popen, scratch: Path) -> None:
    stdout, stderr = process.communicate(timeout=60)  # ends in seconds, though items or tools were mid-way
    assert process.returncode == 130 and stderr.strip().splitlines()[-1] == "harness: interrupted", stderr
    time.sleep(0.5)
    assert processes_naming(str(scratch)) == []
    assert list(scratch.iterdir()) == []


def test_an_interrupted_plan_ends_its_workers_and_their_files(fmu_paths, tmp_path):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    process = started(["plan", str(PROJECT_ROOT / "scenes" / "thesis_scene.json"), "--workers", "2"], scratch)
    wait_for(lambda: any(p.name.startswith("sweep-") and any(p.iterdir()) for p in scratch.iterdir()))
    time.sleep(1.0)
    process.send_signal(signal.SIGINT)
    ended_cleanly(process, scratch)


def test_an_interrupted_derive_ends_the_compiler(tmp_path):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    process = started(["derive", str(PROJECT_ROOT / "modelDescription" / "DoublePendulum.toml"), "--out",
                       str(tmp_path / "out")], scratch)
    wait_for(lambda: processes_naming(f"{scratch}/program-")
             and any("cc1" in p for p in processes_naming(str(scratch))))
    process.send_signal(signal.SIGTERM)
    ended_cleanly(process, scratch)
    assert not list((tmp_path / "out").glob("*.fmu"))


def test_an_interrupted_build_ends_make(tmp_path):
    """The FMUs built on demand into an empty build folder: an interrupt ends cmake and what it started
    (the first program cmake runs, the generator of the objects' C, or a compiler)."""
    scratch, build = tmp_path / "scratch", tmp_path / "build"
    scratch.mkdir()
    process = started(["simulate", "SimplePendulum", "--out", str(tmp_path / "x.csv")], scratch,
                      {"PENDULUM_BUILD_DIR": str(build), "PENDULUM_SKIP_BUILD": "0"})
    wait_for(lambda: any(not p.split()[0].endswith("cmake") for p in processes_naming(str(build))))
    process.send_signal(signal.SIGTERM)
    ended_cleanly(process, scratch)
    assert processes_naming(str(build)) == []


def test_a_second_interrupt_does_not_cut_the_clean_up_short(fmu_paths, tmp_path):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    out = tmp_path / "long.csv"
    process = started(["simulate", "SimplePendulum", "--stop", "2000", "--step", "0.001", "--h", "1e-5", "--quiet",
                       "--out", str(out)], scratch)
    wait_for(lambda: list(scratch.iterdir()))
    time.sleep(1.0)
    for _ in range(3):
        process.send_signal(signal.SIGTERM)
    ended_cleanly(process, scratch)
    assert len(out.read_text().splitlines()) > 10


@pytest.mark.parametrize("case", ["start", "unit", "implementation"])
def test_ssd_features_the_master_does_not_carry_out_are_refused(fmu_paths, tmp_path, case):
    """A start time other than 0, a value in another unit than its variable's, a component asking
    for Model Exchange: one line naming it, never a run that ignores it."""
    folder = ssp_copy(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    edits = {"start": ('startTime="0" stopTime="10.0"', 'startTime="5" stopTime="5.05"'),
             "unit": (r'(<ssv:Parameter name="l0">\s*<ssv:Real) value="1.5"', r'\1 value="1500" unit="mm"'),
             "implementation": ('<ssd:Component name="left" ',
                                '<ssd:Component name="left" implementation="ModelExchange" ')}
    ssd.write_text(ssd_edited(ssd.read_text(), *edits[case]))
    words = {"start": "startTime = 5", "unit": "parameter 'l0' is given in 'mm'",
             "implementation": "'ModelExchange'"}[case]
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")), words)
    assert not (tmp_path / "x.csv").exists()


def test_an_ssv_enumeration_names_its_item(fmu_paths, tmp_path):
    """SSP gives an enumeration's value as its item's name: euler runs as euler (its work counts show it)."""
    folder = ssp_copy(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd_edited(ssd.read_text(), r'(<ssv:Parameter name="solver">\s*)<ssv:Integer value="5" ?/>',
                              r'\1<ssv:Enumeration value="euler"/>'))
    result = harness("run", str(folder), "--stop", "0.1", "--step", "0.1", "--out", str(tmp_path / "x.csv"))
    assert result.returncode == 0, result.stderr
    header, *rows = (tmp_path / "x.csv").read_text().splitlines()
    column = header.split(",").index("left.n_rhs")
    assert float(rows[-1].split(",")[column]) == 100  # euler: one evaluation per substep of h = 0.001
