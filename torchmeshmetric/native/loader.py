"""The one loader of the package's C++ extensions: every source lives in this folder, built once per machine.

Each extension (:data:`EXTENSIONS`) is compiled with :func:`torch.utils.cpp_extension.load` into torch's extensions
directory (``$TORCH_EXTENSIONS_DIR``, by default ``~/.cache/torch_extensions``) under a name that carries a hash of
its sources and flags, so an edited source is rebuilt instead of a stale build reused. A finished build is imported
directly (no ninja run, no build lock). One process builds an extension at a time (the others wait, told by whom);
a build that was killed leaves nothing that blocks the next one (:func:`_build_lock`). A build prints one progress
line to stderr when it starts and one when it ends, and the caller waits for it: no computation runs another
formulation meanwhile. Where a build is impossible (no C++ compiler, no ninja) :func:`load` raises
:class:`NativeBuildError`, whose first line gives the reason (``/bin/sh: 1: c++: not found``), and :func:`try_load`
warns once and returns ``None``; either outcome is kept for the whole process, so one process never mixes
formulations.

Build everything ahead of first use with ``torchmeshmetric build`` or ``python -m torchmeshmetric.native``.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import os
import re
import threading
import time
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from torchmeshmetric._console import say

__all__ = ["EXTENSIONS", "HOME", "NativeBuildError", "NativeExtension", "build", "load", "ready", "try_load"]

HOME = Path(__file__).parent
"""The folder of every C++ source and header of the package (the include directory of every extension)."""

# -ffp-contract=off: no fused multiply-add, so the C++ arithmetic rounds as the torch kernels (and mmetric's compiled
# code) round it, bit for bit; -fno-fast-math: no reassociation either.
_EXACT = ("-O3", "-ffp-contract=off", "-fno-fast-math", "-std=c++17")


@dataclass(frozen=True)
class NativeExtension:
    """One compiled extension: its sources and headers (file names in :data:`HOME`) and compiler flags.

    Attributes:
        sources: the ``.cpp`` files compiled into the extension.
        headers: the headers they include (part of the build's hash: an edited header rebuilds).
        cflags: compiler flags.
        ldflags: linker flags.

    Example:
        >>> bvh = EXTENSIONS["bvh"]
        >>> bvh.sources, "-ffp-contract=off" in bvh.cflags  # exact arithmetic: no fused multiply-add
        (('bvh.cpp', 'deformation_energy.cpp'), True)
    """

    sources: tuple[str, ...]
    headers: tuple[str, ...] = ()
    cflags: tuple[str, ...] = _EXACT
    ldflags: tuple[str, ...] = ()

    def module_name(self, name: str) -> str:
        """The build's module name: ``torchmeshmetric_<name>_<hash of sources, headers and flags>``."""
        digest = hashlib.sha1()
        for file in self.sources + self.headers:
            digest.update((HOME / file).read_bytes())
        digest.update(" ".join(self.cflags + self.ldflags).encode())
        return f"torchmeshmetric_{name}_{digest.hexdigest()[:10]}"


EXTENSIONS: dict[str, NativeExtension] = {
    # The CPU BVH selections (kernels.accel.bvh) and the fused deformation-graph energy (registration.energies).
    "bvh": NativeExtension(
        sources=("bvh.cpp", "deformation_energy.cpp"),
        headers=("parallel.h", "triangle.h"),
        cflags=(*_EXACT, "-fopenmp"),
        ldflags=("-fopenmp",),
    ),
    # mmetric's IBSM rasterizer and its grid sampling's ray caster (mpeg.comparison.ibsm, mpeg.sampling.grid_sampling).
    "ibsm": NativeExtension(
        sources=("ibsm_raster.cpp",), headers=("parallel.h",), cflags=(*_EXACT, "-fopenmp"), ldflags=("-fopenmp",)
    ),
    # mmetric's pcc comparison: the duplicate merge and the neighbour search with ties (mpeg.point_cloud, neighbours).
    # Also the replay of mmetric's std::sort of a cloud's positions (mpeg.comparison.point_order) and the text of the
    # model files mmetric writes (mpeg.core.text_rows).
    "pcc": NativeExtension(
        sources=("mpeg_pcc.cpp", "point_order.cpp", "model_text.cpp"),
        headers=("parallel.h",),
        cflags=(*_EXACT, "-fopenmp"),
        ldflags=("-fopenmp",),
    ),
    # mmetric's PCQM (compare --mode pcqm): its k-d tree searches, quadric fits and pooled features (mpeg.pcqm).
    "pcqm": NativeExtension(
        sources=("pcqm.cpp",), headers=("parallel.h",), cflags=(*_EXACT, "-fopenmp"), ldflags=("-fopenmp",)
    ),
}
"""Every extension of the package, by the name :func:`load` takes."""


class NativeBuildError(RuntimeError):
    """A C++ extension could not be built or imported here (no compiler, no ninja, a read-only cache, ...).

    Example:
        >>> try:
        ...     module = load("bvh")
        ... except NativeBuildError:  # a RuntimeError too: no compiler here, take the pure-torch path
        ...     module = None
        >>> module is None or callable(module.closest_points)
        True
    """


_LOCK = threading.Lock()
_STATE: dict[str, ModuleType | NativeBuildError] = {}
_WARNED: set[str] = set()


def _extension(name: str) -> NativeExtension:
    if name not in EXTENSIONS:
        raise KeyError(f"native: no extension named {name!r}; known: {sorted(EXTENSIONS)}")
    return EXTENSIONS[name]


def _built_path(module_name: str) -> Path:
    from torch.utils.cpp_extension import _get_build_directory

    return Path(_get_build_directory(module_name, verbose=False)) / f"{module_name}.so"


def _import_built(module_name: str) -> ModuleType | None:
    """Import a finished build of this exact source directly, or ``None`` where there is none.

    ``load`` re-runs ninja and takes a file lock in every new process (seconds, and much longer when several
    processes start at once); a finished build is simply imported.
    """
    try:
        path = _built_path(module_name)
        if not path.is_file():
            return None
        spec = importlib.util.spec_from_file_location(module_name, path)
        if spec is None or spec.loader is None:
            return None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    except Exception:  # anything unexpected: the regular (checked) build-and-load path decides
        return None


_TORCH_LOCK = "lock"  # torch.utils.cpp_extension's FileBaton in the build folder: a bare file, no owner recorded
_OWN_LOCK = "torchmeshmetric.lock"  # ours beside it: flock'ed by the building process, holding its id


@contextlib.contextmanager
def _build_lock(name: str, build_dir: Path) -> Iterator[None]:
    """Hold the build of one extension against every other process; a killed build never blocks the next one.

    torch's own lock is a bare file that a killed build leaves behind, and torch then waits on it forever. This lock
    is an advisory ``flock`` beside it, which the kernel releases when its holder dies however it dies; while it is
    held, no live build of this extension exists, so a torch lock file found then is stale and is removed (with one
    line on stderr saying so). A live build by another process is waited for, with one line naming its process id.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover (not POSIX: torch's lock alone)
        yield
        return
    build_dir.mkdir(parents=True, exist_ok=True)
    with open(build_dir / _OWN_LOCK, "a+") as fh:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            holder = fh.read().strip() or "?"
            say(f"torchmeshmetric: waiting for the build of {name!r} by process {holder}...")
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:
            fh.seek(0)
            fh.truncate()
            fh.write(f"{os.getpid()}\n")
            fh.flush()
            _clear_torch_lock(name, build_dir / _TORCH_LOCK)
            yield
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


def _lock_holders(path: Path) -> list[int] | None:
    """The processes that have ``path`` open (a live torch build keeps its lock file open), ``None`` without /proc."""
    proc = Path("/proc")
    if not (proc / "self" / "fd").is_dir():
        return None
    target = os.path.realpath(path)
    holders = []
    for pid in (d for d in os.listdir(proc) if d.isdigit()):
        with contextlib.suppress(OSError):
            fds = os.listdir(proc / pid / "fd")
            if any(os.path.realpath(proc / pid / "fd" / fd) == target for fd in fds):
                holders.append(int(pid))
    return holders


def _clear_torch_lock(name: str, lock: Path) -> None:
    """Remove torch's lock file when no process holds it (its build was killed); wait while one does.

    A build through this loader holds :data:`_OWN_LOCK` too, so a torch lock found while holding it was left by a
    killed build, or is held by a process building the same sources without this lock (another copy of the
    package): those keep the file open, and are waited for.
    """
    announced = False
    while lock.exists():
        holders = _lock_holders(lock)
        if not holders:
            lock.unlink(missing_ok=True)
            say(
                f"torchmeshmetric: removed the stale build lock {str(lock)!r} of {name!r} (the process that "
                "took it is gone: its build was killed); building again"
            )
            return
        if not announced:
            who = ", ".join(str(h) for h in holders)
            say(f"torchmeshmetric: waiting for the build of {name!r} by process {who}...")
            announced = True
        time.sleep(0.2)


def _reason(err: BaseException) -> str:
    """The lines of a failed build that say why (``/bin/sh: 1: c++: not found``, a compiler's ``error:``), as one line.

    torch's message starts with the compile command, which says nothing; the reason comes after it.
    """
    lines = [ln.strip() for ln in str(err).splitlines()[1:] if ln.strip()]
    kept = [
        ln
        for ln in lines
        if not ln.startswith(("[", "FAILED:", "ninja: build stopped")) and not (" -c " in ln and " -o " in ln)
    ]
    why = [ln for ln in kept if re.search(r"not found|no such file|error|fatal|cannot|denied", ln, re.IGNORECASE)]
    picked = (why or kept)[:3]
    first = str(err).strip().splitlines()[0] if str(err).strip() else ""
    return "; ".join(picked) if picked else f"{type(err).__name__}: {first}"


def _compile(name: str, ext: NativeExtension, module_name: str) -> ModuleType:
    """Build (or finish another process's build of) the extension, with a progress line on stderr."""
    from torch.utils.cpp_extension import _get_build_directory
    from torch.utils.cpp_extension import load as torch_load

    with _build_lock(name, Path(_get_build_directory(module_name, verbose=False))):
        done = _import_built(module_name)  # another process finished it while this one waited
        if done is not None:
            return done
        say(f"torchmeshmetric: building the C++ extension {name!r} ({', '.join(ext.sources)}) once for this machine...")
        start = time.perf_counter()
        module = torch_load(
            name=module_name,
            sources=[str(HOME / s) for s in ext.sources],
            extra_cflags=list(ext.cflags),
            extra_ldflags=list(ext.ldflags),
            extra_include_paths=[str(HOME)],
            verbose=False,
        )
    say(f"torchmeshmetric: built {name!r} in {time.perf_counter() - start:.1f} s")
    return module


def ready(name: str) -> bool:
    """Whether the extension is usable without compiling: loaded in this process, or a finished build is cached.

    Args:
        name: a key of :data:`EXTENSIONS`.

    Returns:
        ``True`` when :func:`load` would not compile.

    Example:
        >>> isinstance(ready("bvh"), bool)
        True
    """
    ext = _extension(name)
    state = _STATE.get(name)
    if state is not None:
        return isinstance(state, ModuleType)
    try:
        return _built_path(ext.module_name(name)).is_file()
    except Exception:
        return False


def load(name: str) -> ModuleType:
    """The compiled extension, built first (waiting for it, progress on stderr) where no build is cached.

    Args:
        name: a key of :data:`EXTENSIONS` (``"bvh"``, ``"ibsm"``).

    Returns:
        The extension module.

    Raises:
        NativeBuildError: the extension cannot be built here; raised again by every later call in this process.

    Example:
        >>> hasattr(load("bvh"), "deform_vertices")
        True
    """
    ext = _extension(name)
    with _LOCK:
        state = _STATE.get(name)
        if state is None:
            try:
                module_name = ext.module_name(name)
                state = _import_built(module_name) or _compile(name, ext, module_name)
            except Exception as err:  # no compiler, no ninja, read-only cache, ...
                state = NativeBuildError(
                    f"native: the C++ extension {name!r} could not be built: {_reason(err)}\n"
                    f"{type(err).__name__}: {err}"
                )
                state.__cause__ = err
            _STATE[name] = state
    if isinstance(state, NativeBuildError):
        raise state
    return state


def try_load(name: str) -> ModuleType | None:
    """:func:`load`, or ``None`` with one ``RuntimeWarning`` per process where the extension cannot be built.

    For callers with an exact pure-torch (or numpy) formulation of the same computation; the outcome is fixed for
    the process, so one result never mixes the two.

    Args:
        name: a key of :data:`EXTENSIONS`.

    Returns:
        The extension module, or ``None``.

    Example:
        >>> try_load("bvh") is not None
        True
    """
    try:
        return load(name)
    except NativeBuildError as err:
        if name not in _WARNED:
            _WARNED.add(name)
            warnings.warn(
                f"torchmeshmetric: {str(err).splitlines()[0]}; falling back to the exact pure formulation, which is "
                "slower on the CPU.",
                RuntimeWarning,
                stacklevel=2,
            )
        return None


def build(names: Sequence[str] | None = None) -> dict[str, Path]:
    """Build (or find built) the given extensions, all by default, ahead of first use.

    Args:
        names: keys of :data:`EXTENSIONS`; ``None``: every extension.

    Returns:
        The path of each extension's compiled module, by name.

    Raises:
        NativeBuildError: an extension cannot be built here.

    Example:
        >>> build(["bvh"])["bvh"].suffix
        '.so'
    """
    return {name: Path(str(load(name).__file__)) for name in (EXTENSIONS if names is None else names)}
