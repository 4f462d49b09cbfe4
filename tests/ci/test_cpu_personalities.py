"""``python -m tests.cpu_personalities``: each personality's environment reaches the command; ``--only`` picks one."""

from __future__ import annotations

import sys

import pytest

from tests.cpu_personalities import OTHER_CPUS, main

SHOW = "import os; print(os.environ['ATEN_CPU_CAPABILITY'], os.environ['MKL_CBWR'])"


def test_every_personality_runs_the_command_in_its_environment(capfd):
    assert main([sys.executable, "-c", SHOW]) == 0
    out = capfd.readouterr().out
    for name, env in OTHER_CPUS.items():
        assert f"=== CPU personality '{name}'" in out
        assert f"{env['ATEN_CPU_CAPABILITY']} {env['MKL_CBWR']}\n" in out


def test_only_runs_one_personality_and_returns_the_commands_status(capfd):
    assert main(["--only", "scalar", sys.executable, "-c", SHOW]) == 0
    out = capfd.readouterr().out
    assert "=== CPU personality 'scalar'" in out and "default COMPATIBLE\n" in out
    assert "'avx2'" not in out
    assert main(["--only", "avx2", sys.executable, "-c", "raise SystemExit(3)"]) == 3


@pytest.mark.parametrize("argv", [["--only"], ["--only", "scalar"], ["--only", "sse", "true"]])
def test_only_needs_a_known_personality_and_a_command(argv):
    with pytest.raises(SystemExit, match="--only takes one of \\['scalar', 'avx2'\\] and a command"):
        main(argv)
