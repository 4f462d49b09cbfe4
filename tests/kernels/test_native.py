"""The one native loader: built before use with a progress line, the outcome fixed per process, the build command."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
import torch

from torchmeshmetric import native
from torchmeshmetric.cli import main
from torchmeshmetric.kernels import select
from torchmeshmetric.native import loader


@pytest.fixture
def fresh(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """A process that has loaded nothing and finds no finished build: every load compiles (faked, recorded)."""
    import torch.utils.cpp_extension as cpp

    real = native.load("bvh")  # the real module, handed out by the fake compiler below
    built: list[str] = []

    def fake_compile(name: str, **kwargs: object) -> object:
        built.append(name)
        return real

    monkeypatch.setattr(cpp, "load", fake_compile)
    monkeypatch.setattr(loader, "_import_built", lambda name: None)
    monkeypatch.setattr(loader, "_STATE", {})
    return built


def test_a_first_use_builds_first_with_one_progress_line_then_never_again(fresh, capsys):
    cpu = torch.device("cpu")
    # A tiny problem on a process without a build: "auto" builds and uses the extension (no other formulation).
    assert select.auto_backend_name(cpu, torch.float64, 10) == "bvh"
    err = capsys.readouterr().err
    assert err.count("building the C++ extension 'bvh'") == 1 and err.count("built 'bvh' in") == 1
    assert len(fresh) == 1 and fresh[0].startswith("torchmeshmetric_bvh_")
    assert select.auto_backend_name(cpu, torch.float64, 10) == "bvh"
    assert native.ready("bvh") and len(fresh) == 1 and capsys.readouterr().err == ""


def test_a_failed_build_is_kept_for_the_process(monkeypatch):
    import torch.utils.cpp_extension as cpp

    attempts: list[str] = []

    def no_compiler(name: str, **kwargs: object) -> object:
        attempts.append(name)
        raise OSError("no C++ compiler")

    monkeypatch.setattr(cpp, "load", no_compiler)
    monkeypatch.setattr(loader, "_import_built", lambda name: None)
    monkeypatch.setattr(loader, "_STATE", {})
    monkeypatch.setattr(loader, "_WARNED", {"bvh"})  # the warning itself: test_accel_fallback.py
    for _ in range(3):
        assert native.try_load("bvh") is None
        assert not native.ready("bvh")
    assert len(attempts) == 1  # later calls do not retry: a process never switches formulation mid-way


def test_module_name_hashes_sources_and_flags():
    ext = native.EXTENSIONS["bvh"]
    name = ext.module_name("bvh")
    assert name.startswith("torchmeshmetric_bvh_") and len(name) == len("torchmeshmetric_bvh_") + 10
    other = native.NativeExtension(ext.sources, ext.headers, (*ext.cflags, "-DTEST"), ext.ldflags)
    assert other.module_name("bvh") != name
    assert all((native.HOME / f).is_file() for e in native.EXTENSIONS.values() for f in e.sources + e.headers)


def test_every_cpp_source_of_the_package_lives_in_the_native_home():
    package = native.HOME.parent
    sources = {p for ext in ("*.cpp", "*.h", "*.cu", "*.hpp") for p in package.rglob(ext)}
    assert sources and {p.parent for p in sources} == {native.HOME}
    listed = {native.HOME / f for e in native.EXTENSIONS.values() for f in e.sources + e.headers}
    assert listed == sources


def test_build_command(capsys):
    assert main(["build", "bvh"]) == 0
    assert "bvh: " in capsys.readouterr().err
    assert main(["build", "nope"]) == 1
    assert "unknown extension(s) ['nope']" in capsys.readouterr().err


def test_python_m_native_builds():
    env = {**os.environ, "PYTHONPATH": str(native.HOME.parents[1])}  # this checkout, not an installed copy
    done = subprocess.run(
        [sys.executable, "-m", "torchmeshmetric.native", "bvh"], capture_output=True, text=True, timeout=600, env=env
    )
    assert done.returncode == 0, done.stderr
    assert "bvh: " in done.stderr and native.EXTENSIONS["bvh"].module_name("bvh") in done.stderr
