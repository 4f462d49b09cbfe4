"""The README's commands install what they need: the demo the runtime dependencies, the tests the test extra.

And CI runs them as a fresh machine would: an empty extension cache every time, a missing compiler said loudly.
"""

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


def _run(
    tmp_path: Path, *command: str, env_extra: dict[str, str] | None = None, stderr: list[str] | None = None
) -> list[str]:
    """Run a copy of .ci/bootstrap.sh with a fake python/pip on PATH; return the commands it ran (and its stderr)."""
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
    done = subprocess.run(
        ["bash", str(repo / ".ci" / "bootstrap.sh"), *command], check=True, env=env, cwd=tmp_path, capture_output=True
    )
    if stderr is not None:
        stderr.append(done.stderr.decode())
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


def test_a_missing_compiler_is_said_loudly(tmp_path):
    err: list[str] = []
    _run(tmp_path, "torchmeshmetric", "demo", stderr=err)
    assert "no C++ compiler" not in err[0]  # this machine kind has one (c++ on PATH)
    ran = _run(tmp_path, "torchmeshmetric", "demo", env_extra={"CXX": "no-such-compiler-here"}, stderr=err)
    assert "bootstrap: no C++ compiler (no-such-compiler-here) on PATH" in err[1]
    assert ran == ["torchmeshmetric demo"]  # the command still runs (pure formulations)


def test_ci_run_gives_every_run_a_fresh_empty_extension_cache(tmp_path):
    repo = tmp_path / "repo"
    (repo / ".ci").mkdir(parents=True)
    shutil.copy(ROOT / ".ci" / "run", repo / ".ci" / "run")
    log = tmp_path / "seen.txt"
    # A stand-in bootstrap: records the cache folder the suite would get, whether it exists and what it holds.
    (repo / ".ci" / "bootstrap.sh").write_text(
        f'd="$TORCH_EXTENSIONS_DIR"; echo "$d $(test -d "$d" && echo dir) $(ls -A "$d" | wc -l) $*" >> "{log}"\n'
        'touch "$d/left-by-the-suite"\n'
    )
    env = {k: v for k, v in os.environ.items() if k != "TORCH_EXTENSIONS_DIR"} | {"TMPDIR": str(tmp_path)}
    for _ in range(2):
        subprocess.run(["bash", str(repo / ".ci" / "run")], check=True, env=env, cwd=tmp_path)
    seen = [line.split(" ", 3) for line in log.read_text().splitlines()]
    # Per run: the pinned tests as other CPUs meet the new cache empty (the first build, as on a new machine), then
    # the README command and the whole suite as the scalar CPU in the same cache (the extensions built once per run).
    pinned = "python -m tests.cpu_personalities python -m pytest -m pinned -n 2 -q"
    scalar = "python -m tests.cpu_personalities --only scalar python -m pytest -n 2 -q"
    # ... and between them the default demo once, against the golden the docs' quoted figures are checked against
    demo = "python -m pytest -q tests/docs/test_tutorial_figures.py"
    run = [["dir", "0", pinned], ["dir", "1", "python -m pytest -n 2"], ["dir", "1", demo], ["dir", "1", scalar]]
    assert [s[1:] for s in seen] == run * 2
    assert len({s[0] for s in seen[:4]}) == len({s[0] for s in seen[4:]}) == 1 and seen[0][0] != seen[4][0]
    assert all(Path(s[0]).parent == tmp_path for s in seen)
    assert not any(Path(s[0]).exists() for s in seen)  # removed after each run
