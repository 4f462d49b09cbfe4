"""The README's commands install what they need: the demo the runtime dependencies, the tests the test extra."""

import os
import shutil
import stat
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")


def _fake_tool(folder: Path, name: str, log: Path, script: str = "") -> None:
    path = folder / name
    path.write_text(f'#!/usr/bin/env bash\necho "{name} $*" >> "{log}"\n{script}exit 0\n')
    path.chmod(path.stat().st_mode | stat.S_IXUSR)


def _run(tmp_path: Path, *command: str, env_extra: dict[str, str] | None = None) -> list[str]:
    """Run a copy of .ci/bootstrap.sh with a fake python/pip on PATH; return the commands it ran."""
    repo = tmp_path / "repo"
    if not repo.exists():
        (repo / ".ci").mkdir(parents=True)
        shutil.copy(ROOT / ".ci" / "bootstrap.sh", repo / ".ci" / "bootstrap.sh")
        shutil.copy(ROOT / "pyproject.toml", repo / "pyproject.toml")
    bin_dir, log = tmp_path / "bin", tmp_path / "log.txt"
    bin_dir.mkdir(exist_ok=True)
    log.write_text("")
    _fake_tool(bin_dir, "python", log, 'if [[ "$1" == "-c" && "$2" == *sys.prefix* ]]; then echo _fake_env; fi\n')
    _fake_tool(bin_dir, "torchmeshmetric", log)
    env = {k: v for k, v in os.environ.items() if k not in ("CONDA_PREFIX", "TORCHMESHMETRIC_EXTRAS")}
    env |= {"PATH": f"{bin_dir}:/usr/bin:/bin", "VIRTUAL_ENV": str(tmp_path / "env"), **(env_extra or {})}
    subprocess.run(["bash", str(repo / ".ci" / "bootstrap.sh"), *command], check=True, env=env, cwd=tmp_path)
    return [line for line in log.read_text().splitlines() if " pip " in line or not line.startswith("python -c")]


def test_demo_command_installs_runtime_dependencies_only(tmp_path):
    ran = _run(tmp_path, "torchmeshmetric", "demo")
    assert ran == ["python -m pip install -q -e .", "torchmeshmetric demo"]


def test_test_command_installs_the_test_extra(tmp_path):
    ran = _run(tmp_path, "python", "-m", "pytest", "-n", "2")
    assert ran == ["python -m pip install -q -e .[test]", "python -m pytest -n 2"]


def test_second_run_installs_nothing_and_extras_have_their_own_stamp(tmp_path):
    assert _run(tmp_path, "torchmeshmetric", "demo")[0].startswith("python -m pip")
    assert _run(tmp_path, "torchmeshmetric", "demo") == ["torchmeshmetric demo"]
    # the runtime stamp does not stand for the test extra
    assert _run(tmp_path, "python", "-m", "pytest")[0] == "python -m pip install -q -e .[test]"
    assert _run(tmp_path, "python", "-m", "pytest") == ["python -m pytest"]


def test_extras_override(tmp_path):
    ran = _run(tmp_path, "torchmeshmetric", "demo", env_extra={"TORCHMESHMETRIC_EXTRAS": "docs"})
    assert ran[0] == "python -m pip install -q -e .[docs]"
