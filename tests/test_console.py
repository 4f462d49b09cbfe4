"""``say``: one line on stderr in one write, so that ranks sharing a stderr never merge their lines."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from torchmeshmetric._console import say

ROOT = Path(__file__).resolve().parents[1]


class _Recorder:
    def __init__(self) -> None:
        self.writes: list[str] = []
        self.flushes = 0

    def write(self, text: str) -> int:
        self.writes.append(text)
        return len(text)

    def flush(self) -> None:
        self.flushes += 1


def test_a_line_is_one_write_with_its_newline_then_a_flush(monkeypatch: pytest.MonkeyPatch) -> None:
    rec = _Recorder()
    monkeypatch.setattr(sys, "stderr", rec)
    say("ctc-campaign: anchor sequence 'sphere' frame 0: GridD1 57.4928")
    assert rec.writes == ["ctc-campaign: anchor sequence 'sphere' frame 0: GridD1 57.4928\n"]
    assert rec.flushes == 1


def test_no_stderr_is_no_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stderr", None)
    say("nobody listens")  # pythonw or a closed stderr: nothing written, nothing raised


_WRITER = """
import sys
from torchmeshmetric._console import say
for i in range(2000):
    say(f"line {sys.argv[1]} {i} " + "x" * 150)
"""


def test_two_unbuffered_processes_on_one_pipe_never_merge_lines() -> None:
    """The failure of torchrun's ranks under PYTHONUNBUFFERED=1, where print() wrote text and newline apart.

    With print() this setting merged 367 of 6000 lines (two processes, 3000 lines each, this machine); ``say``
    makes that impossible, not unlikely, so any merged line fails the test.
    """
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "PYTHONPATH": str(ROOT)}
    r, w = os.pipe()
    procs = [subprocess.Popen([sys.executable, "-c", _WRITER, tag], stderr=w, env=env, cwd=ROOT) for tag in ("A", "B")]
    os.close(w)
    with os.fdopen(r) as fh:
        text = fh.read()
    assert [p.wait(timeout=60) for p in procs] == [0, 0]
    lines = text.splitlines()
    assert len(lines) == 4000
    assert all(line.count("line ") == 1 and line.endswith("x" * 150) for line in lines)
    for tag in ("A", "B"):
        assert [int(line.split()[2]) for line in lines if line.split()[1] == tag] == list(range(2000))


def test_the_package_prints_nothing_to_stderr_but_through_say() -> None:
    """One way to say a line: a print(..., file=sys.stderr) anywhere would bring the merged lines back."""
    found = []
    for path in sorted((ROOT / "torchmeshmetric").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            to_stderr = isinstance(node, ast.Call) and getattr(node.func, "id", None) == "print"
            if to_stderr and any(k.arg == "file" and ast.unparse(k.value) == "sys.stderr" for k in node.keywords):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert found == []


def test_warnings_as_lines_prints_one_line_without_the_source() -> None:
    # Review R #11: the commands' warnings showed Python's source file, line and code (`records.write(key, record)`).
    # In a process of its own: pytest records the warnings of its tests instead of printing them.
    code = (
        "import warnings\n"
        "from torchmeshmetric._console import warnings_as_lines\n"
        "with warnings_as_lines('ctc-campaign'):\n"
        "    warnings.warn('cannot store frame records in the cache folder /archive', UserWarning)\n"
        "    warnings.warn('not converged', RuntimeWarning)\n"
        "warnings.warn('after', UserWarning)\n"
    )
    root = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": root + os.pathsep + os.environ.get("PYTHONPATH", "")}
    err = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stderr
    lines = err.splitlines()
    assert lines[:2] == [
        "torchmeshmetric ctc-campaign: warning: cannot store frame records in the cache folder /archive",
        "torchmeshmetric ctc-campaign: RuntimeWarning: not converged",
    ]
    assert "UserWarning: after" in lines[2]  # Python's own format again once the command is over
