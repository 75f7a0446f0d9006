"""The style a machine keeps: ruff over the Python (pyproject.toml's [tool.ruff]), clang-format over the C
(.clang-format), and commit subjects under 72 characters with the why in the body."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
# commits from this one on follow the rule for their messages; those before it are as they were written
RULE_SINCE = "2026-12-07T22:30:00Z"


def tool(name: str) -> str:
    found = BIN / name if (BIN / name).exists() else shutil.which(name)
    if found is None:
        pytest.skip(f"{name} is not installed (pip install -e '.[test]' installs it)")
    return str(found)


def test_python_passes_ruff():
    result = subprocess.run([tool("ruff"), "check", "--output-format", "concise", "."], cwd=ROOT, capture_output=True,
                            text=True)
    assert result.returncode == 0, result.stdout[-3000:]


def test_c_is_formatted_as_clang_format_keeps_it():
    files = subprocess.run(["git", "ls-files", "*.c", "*.h"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    result = subprocess.run([tool("clang-format"), "--dry-run", "-Werror", *files], cwd=ROOT, capture_output=True,
                            text=True)
    assert result.returncode == 0, result.stderr[-3000:]


def test_commit_subjects_are_short_and_say_why_in_the_body():
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    log = subprocess.run(["git", "log", f"--since={RULE_SINCE}", "--format=%H%x00%s%x00%b%x01"], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout
    for entry in filter(str.strip, log.split("\x01")):
        commit, subject, body = entry.strip("\n").split("\x00")
        assert len(subject) < 72, (commit[:10], subject)
        assert body.strip(), (commit[:10], subject, "no body: say why")
