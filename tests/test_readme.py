"""The README's quickstart runs as written, and its two commands are the ones CI and the docs use."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def _blocks(lang):
    return re.findall(rf"```{lang}\n(.*?)```", README, flags=re.S)


def test_quickstart_runs(capsys):
    (code,) = _blocks("python")
    assert len(code.strip().splitlines()) <= 15
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in out] == ["surface_k_minus_1", "surface_k", "vertex_k_minus_1", "vertex_k"]
    # the registration is exact, so the k-1 and k sets agree
    ave = {line.split()[0]: float(line.split()[2]) for line in out}
    assert ave["surface_k"] == pytest.approx(ave["surface_k_minus_1"], rel=1e-3)


def test_two_commands_match_ci():
    (bash,) = _blocks("bash")
    commands = [line.split("#")[0].strip() for line in bash.strip().splitlines()]
    assert commands == ["bash .ci/bootstrap.sh torchmeshmetric demo", "bash .ci/bootstrap.sh python -m pytest -n 2"]
    assert "bash .ci/bootstrap.sh python -m pytest -n 2" in (ROOT / ".ci" / "run").read_text()
