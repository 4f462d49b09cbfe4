"""A killed build never blocks a later one, a live build is waited for by name, and a failed build says why (issue 41,
theme 2)."""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from torchmeshmetric import native
from torchmeshmetric.cli import main
from torchmeshmetric.native import loader

TINY = """#include <pybind11/pybind11.h>
int answer() { return 42; }
PYBIND11_MODULE(TORCH_EXTENSION_NAME, m) { m.def("answer", &answer); }
"""

# Loads a one-function extension through the package's loader (its sources in argv[1]), printing its answer.
SCRIPT = """
import sys
from pathlib import Path
from torchmeshmetric.native import loader
loader.HOME = Path(sys.argv[1])
loader.EXTENSIONS["tiny"] = loader.NativeExtension(("tiny.cpp",), cflags=("-O0",))
print(loader.EXTENSIONS["tiny"].module_name("tiny"), flush=True)
print(loader.load("tiny").answer(), flush=True)
"""

# torch's message for a missing compiler (torch 2.x, ``CXX=/nonexistent/c++``), as the loader receives it.
NO_COMPILER = (
    "Error building extension 'x': [1/2] /nonexistent/c++ -MMD -MF tiny.o.d -fPIC -std=c++20 -c /t/tiny.cpp "
    "-o tiny.o \n"
    "FAILED: [code=127] tiny.o \n/nonexistent/c++ -MMD -MF tiny.o.d -fPIC -std=c++20 -c /t/tiny.cpp -o tiny.o \n"
    "/bin/sh: 1: /nonexistent/c++: not found\nninja: build stopped: subcommand failed.\n"
)


def _start(tmp_path: Path, **env: str) -> subprocess.Popen[str]:
    environ = {**os.environ, "TORCH_EXTENSIONS_DIR": str(tmp_path / "ext"), "PYTHONPATH": str(native.HOME.parents[1])}
    return subprocess.Popen(
        [sys.executable, "-c", SCRIPT, str(tmp_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**environ, **env},
        start_new_session=True,  # its own process group: the kill reaches ninja and the compiler too
    )


@pytest.mark.slow
def test_a_killed_build_does_not_block_the_next_one(tmp_path):
    (tmp_path / "tiny.cpp").write_text(TINY)
    first = _start(tmp_path)
    assert first.stdout is not None
    module = first.stdout.readline().strip()
    lock = tmp_path / "ext" / module / "lock"  # torch's FileBaton, taken for the whole build
    deadline = time.monotonic() + 300
    while not lock.exists():
        assert first.poll() is None and time.monotonic() < deadline, "the build never started"
        time.sleep(0.05)
    os.killpg(first.pid, signal.SIGKILL)  # as an OOM kill or a closed terminal would end it, mid-build
    first.wait()
    assert lock.exists()  # what torch alone would wait on forever

    second = _start(tmp_path)
    out, err = second.communicate(timeout=600)
    assert second.returncode == 0, err
    assert out.split() == [module, "42"]
    assert "removed the stale build lock" in err and "'tiny'" in err and "waiting" not in err
    assert not lock.exists()


def test_a_live_build_is_waited_for_and_named(tmp_path, capsys):
    build_dir = tmp_path / "build"
    build_dir.mkdir()
    with open(build_dir / "torchmeshmetric.lock", "a+") as held:  # another process's build, in progress
        fcntl.flock(held.fileno(), fcntl.LOCK_EX)
        held.write("4242\n")
        held.flush()
        (build_dir / "lock").touch()  # torch's lock of that live build: not stale, never removed
        entered = threading.Event()

        def build() -> None:
            with loader._build_lock("tiny", build_dir):
                entered.set()

        t = threading.Thread(target=build)
        t.start()
        time.sleep(0.5)
        assert not entered.is_set() and (build_dir / "lock").exists()
        (build_dir / "lock").unlink()  # the live build ends: torch removes its lock, the kernel releases ours
        fcntl.flock(held.fileno(), fcntl.LOCK_UN)
    t.join(timeout=30)
    assert entered.is_set()
    err = capsys.readouterr().err
    assert "waiting for the build of 'tiny' by process 4242" in err and "stale" not in err
    assert (build_dir / "torchmeshmetric.lock").read_text() == f"{os.getpid()}\n"


def test_the_missing_compiler_error_keeps_its_reason(monkeypatch, capsys):
    import torch.utils.cpp_extension as cpp

    def no_compiler(*args: object, **kwargs: object) -> object:
        raise RuntimeError(NO_COMPILER)

    monkeypatch.setattr(cpp, "load", no_compiler)
    monkeypatch.setattr(loader, "_import_built", lambda name: None)
    monkeypatch.setattr(loader, "_STATE", {})
    with pytest.raises(loader.NativeBuildError) as info:
        loader.load("bvh")
    first = str(info.value).splitlines()[0]
    assert first == "native: the C++ extension 'bvh' could not be built: /bin/sh: 1: /nonexistent/c++: not found"
    assert "ninja: build stopped" in str(info.value)  # the whole output is kept below the first line
    monkeypatch.setattr(loader, "_STATE", {})
    assert main(["build", "bvh"]) == 1
    line = capsys.readouterr().err.splitlines()[-1]
    assert line.endswith("could not be built: /bin/sh: 1: /nonexistent/c++: not found"), line


@pytest.mark.slow
def test_a_real_missing_compiler_is_named(tmp_path):
    (tmp_path / "tiny.cpp").write_text(TINY)
    done = _start(tmp_path, CXX=str(tmp_path / "no-such-c++"))
    _, err = done.communicate(timeout=600)
    assert done.returncode == 1
    assert f"could not be built: /bin/sh: 1: {tmp_path / 'no-such-c++'}: not found" in err, err
