"""The compatibility record: what each importer and validator did with the FMUs in this test run,
written to docs/compatibility.md (with a reference result per FMU in docs/compatibility/) when the
run was the whole test suite, else to build/compatibility.md.

A test declares its row with a marker whose fields may name the test's parameters:

    @pytest.mark.compatibility(importer="Wine (tools/fmu_driver.c)", version="{version}", interface="CS",
                               platform="{platform}", criterion="x86_64 Linux binary, within 1e-11")

and reports what it measured through the `compatibility` fixture: `compatibility.agrees(fmu,
difference)`. A test that is skipped leaves its row "not run" with the skip's reason; one that
fails leaves it "fails". Rows of several tests with the same importer, version, interface and
platform merge.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import pytest

OUTCOMES = ("agrees", "not run", "fails")  # in rising order of concern: a merged row takes the worst


@dataclass
class Row:
    importer: str
    version: str
    interface: str
    platform: str
    criterion: str
    outcome: str = "agrees"
    reasons: list[str] = field(default_factory=list)
    differences: dict[str, float | None] = field(default_factory=dict)  # FMU -> largest difference (None: a check)

    @property
    def key(self) -> tuple[str, str, str, str]:
        return self.importer, self.version, self.interface, self.platform

    def agrees(self, fmu: str, difference: float | None = None) -> None:
        """The FMU passed: with the largest difference measured, or None for a check without one."""
        if difference is None:
            self.differences.setdefault(fmu, None)
        else:
            self.differences[fmu] = max(self.differences.get(fmu) or 0.0, difference)

    def worsen(self, outcome: str, reason: str) -> None:
        if OUTCOMES.index(outcome) > OUTCOMES.index(self.outcome) and not (outcome == "not run" and self.differences):
            self.outcome = outcome
        if reason and reason not in self.reasons:
            self.reasons.append(reason)


@dataclass
class Record:
    rows: dict[tuple[str, str, str, str], Row] = field(default_factory=dict)
    expected: set[str] = field(default_factory=set)  # node ids of the tests that contribute a row
    reported: set[str] = field(default_factory=set)
    references: dict[str, "Reference"] = field(default_factory=dict)  # FMU -> its reference result

    def row(self, marker, params: dict) -> Row:
        fields = {k: str(v).format(**params) for k, v in marker.kwargs.items()}
        made = Row(**fields)
        return self.rows.setdefault(made.key, made)

    def merge(self, rows: list[Row], expected: set[str], reported: set[str], references: dict) -> None:
        """Adds what another process of the same run recorded (a parallel test worker)."""
        for row in rows:
            mine = self.rows.setdefault(row.key, Row(row.importer, row.version, row.interface, row.platform,
                                                     row.criterion))
            for fmu, difference in row.differences.items():
                mine.agrees(fmu, difference)
            for reason in row.reasons or [""]:
                mine.worsen(row.outcome, reason)
        self.expected |= expected
        self.reported |= reported
        self.references.update(references)


def _format_difference(value: float) -> str:
    if value == 0.0:
        return "0 (bit for bit)"
    return f"{value:.1e}" if math.isfinite(value) else "inf"


def render(record: Record) -> str:
    rows = sorted(record.rows.values(), key=lambda r: (r.importer, r.version, r.interface, r.platform))
    counts = {outcome: sum(r.outcome == outcome for r in rows) for outcome in OUTCOMES}
    lines = [
        "# Compatibility record",
        "",
        "Written by the test command (`./run test`): every importer and validator that runs on this machine, each",
        "FMU in each FMI version, interface and platform it covers. \"Largest difference\" is the largest",
        "|a - b| / max(1, |a|) over every float output at every communication point, against what the",
        "criterion names; the reference results are in `docs/compatibility/` (how to reproduce them is below).",
        "",
        "Known issue of an importer: OMSimulator 3.0 refuses every FMI 3.0 FMU of this project (\"erroneous",
        "dependencies detected\"): it reads FMI 3.0 `dependencies`, which are value references, as FMI 2.0",
        "indices. The way round: give it the FMI 2.0 FMUs, which it runs in agreement with the harness",
        "([import into other tools](how-to/import-into-tools.md)).",
        "",
        f"{len(rows)} rows: {counts['agrees']} agree, {counts['not run']} not run here (each with its reason), "
        f"{counts['fails']} fail.",
        "",
        "| importer or validator | FMI | interface | platform | criterion | result | FMUs | largest difference |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        measured = {f: d for f, d in row.differences.items() if d is not None}
        if measured:
            worst_fmu = max(measured, key=lambda f: measured[f])
            worst = _format_difference(row.differences[worst_fmu])
            largest = worst if measured[worst_fmu] == 0.0 else f"{worst} ({worst_fmu})"
        else:
            largest = "-"
        result = row.outcome + (f": {'; '.join(row.reasons)}" if row.reasons else "")
        lines.append(f"| {row.importer} | {row.version} | {row.interface} | {row.platform} | {row.criterion} | "
                     f"{result} | {len(row.differences)} | {largest} |")
    lines += ["", "## Reference results", "",
              "One per FMU, from the FMI 2.0 FMU's x86_64 Linux binary in Co-Simulation through the harness, at the",
              "FMU's start values (solver rk4 at its default h for the objects). `<id>_ref.opt` holds the settings",
              "in the form of the FMI cross-check; the command reproduces the file exactly.", "",
              "| FMU | reference | command |", "|---|---|---|"]
    for fmu, reference in sorted(record.references.items()):
        lines.append(f"| {fmu} | [`{fmu}_ref.csv`](compatibility/{fmu}_ref.csv) | `{reference.command}` |")
    return "\n".join(lines) + "\n"


@dataclass
class Reference:
    command: str  # reproduces the file
    table: str    # the CSV text
    options: str  # <id>_ref.opt: the settings in the form of the FMI cross-check


class CompatibilityPlugin:
    """Collects the rows over a session and writes them at its end."""

    def __init__(self, documents: Path, fallback: Path):
        self.record = Record()
        self.documents, self.fallback = documents, fallback
        self.rows_by_node: dict[str, Row] = {}
        self.deselected = 0
        self.files_run: set[Path] = set()

    @pytest.hookimpl(trylast=True)
    def pytest_collection_modifyitems(self, items) -> None:
        self.record.expected = {item.nodeid for item in items if item.get_closest_marker("compatibility")}
        self.files_run = {Path(item.path) for item in items}

    def pytest_deselected(self, items) -> None:
        self.deselected += len(items)

    @pytest.hookimpl(tryfirst=True)
    def pytest_runtest_protocol(self, item) -> None:
        marker = item.get_closest_marker("compatibility")
        if marker is not None:  # declared before any fixture runs, so that a skip in one is recorded
            params = getattr(item, "callspec", None)
            item.compatibility_row = self.rows_by_node[item.nodeid] = \
                self.record.row(marker, params.params if params else {})

    def pytest_runtest_logreport(self, report) -> None:
        row = self.rows_by_node.get(report.nodeid)
        if row is None:
            return
        if report.skipped:
            reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
            row.worsen("not run", reason.removeprefix("Skipped: "))
        elif report.failed:
            row.worsen("fails", f"{report.nodeid.split('::')[-1]} failed")
        if report.when == "teardown":
            self.record.reported.add(report.nodeid)

    @pytest.hookimpl(optionalhook=True)
    def pytest_testnodedown(self, node, error) -> None:
        """A parallel worker (pytest-xdist) finished: its part of the record joins this one's."""
        part = getattr(node, "workeroutput", {}).get("compatibility")
        if part is None:
            return
        self.record.merge([Row(**row) for row in part["rows"]], set(part["expected"]), set(part["reported"]),
                          {fmu: Reference(**reference) for fmu, reference in part["references"].items()})
        self.files_run |= {Path(name) for name in part["files_run"]}
        self.deselected = max(self.deselected, part["deselected"])  # every worker collects the whole run

    def pytest_sessionfinish(self, session) -> None:
        if hasattr(session.config, "workeroutput"):  # a parallel worker: the controller writes the record
            record = self.record
            session.config.workeroutput["compatibility"] = dict(
                rows=[asdict(row) for row in record.rows.values()], expected=sorted(record.expected),
                reported=sorted(record.reported), references={k: asdict(v) for k, v in record.references.items()},
                files_run=sorted(str(path) for path in self.files_run), deselected=self.deselected)
            return
        if not self.record.rows:
            return
        # The documents hold a whole run only: every test file (in the layers' folders), nothing deselected, every
        # row's test reported.
        every_file = set(Path(self.documents.parent.parent, "tests").glob("*/test_*.py")) <= self.files_run
        complete = every_file and not self.deselected and self.record.expected <= self.record.reported
        target = self.documents if complete else self.fallback
        folder = target.parent / target.stem
        folder.mkdir(parents=True, exist_ok=True)
        for fmu, reference in self.record.references.items():
            (folder / f"{fmu}_ref.csv").write_text(reference.table)
            (folder / f"{fmu}_ref.opt").write_text(reference.options)
        target.write_text(render(self.record))
