"""Just-in-time build of the C++ BVH extension (``bvh.cpp``), compiled once and cached by torch.

The extension is compiled with :func:`torch.utils.cpp_extension.load` into torch's extensions directory
(``$TORCH_EXTENSIONS_DIR``, by default ``~/.cache/torch_extensions``); later imports reuse the cached build.
When compilation is impossible (no C++ compiler, no ``ninja``), :func:`load_bvh` warns once and returns
``None``; the callers then use an exact pure-torch path.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import threading
import warnings
from pathlib import Path
from types import ModuleType

__all__ = ["bvh_ready", "load_bvh"]

_SOURCES = [Path(__file__).with_name(n) for n in ("bvh.cpp", "deformation_energy.cpp")]
_HEADERS = [Path(__file__).with_name(n) for n in ("parallel.h", "triangle.h")]
_LOCK = threading.Lock()
_STATE: dict[str, ModuleType | None] = {}

# -ffp-contract=off: no fused multiply-add, so the C++ squared distances equal the torch kernel's bit for bit.
_CFLAGS = ["-O3", "-fopenmp", "-ffp-contract=off", "-fno-fast-math", "-std=c++17"]


def _import_built(name: str) -> ModuleType | None:
    """Import an already built extension directly, skipping ``load``'s ninja run and build-directory lock.

    ``load`` re-runs ninja and takes a file lock in every new process (seconds, and much longer when several
    processes start at once); a finished build of this exact source is simply imported.
    """
    try:
        from torch.utils.cpp_extension import _get_build_directory

        path = Path(_get_build_directory(name, verbose=False)) / f"{name}.so"
        if not path.is_file():
            return None
        spec = importlib.util.spec_from_file_location(name, path)
        if spec is None or spec.loader is None:
            return None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    except Exception:  # anything unexpected: fall back to the regular (checked) build-and-load path
        return None


@functools.cache
def _module_name() -> str:
    # The source hash in the name makes an edited source rebuild instead of reusing a stale cache.
    digest = hashlib.sha1(b"".join(p.read_bytes() for p in _SOURCES + _HEADERS)).hexdigest()[:10]
    return f"torchmeshmetric_bvh_{digest}"


def bvh_ready() -> bool:
    """Whether the extension can be used without compiling: already loaded, or a finished build is cached.

    ``backend="auto"`` then uses it for problems of any size (it beats the brute force from ten points on); before
    the first build it keeps tiny problems on the brute force, so they never pay the compilation.
    """
    state = _STATE.get("bvh", False)
    if state is not False:
        return state is not None
    try:
        from torch.utils.cpp_extension import _get_build_directory

        name = _module_name()
        return (Path(_get_build_directory(name, verbose=False)) / f"{name}.so").is_file()
    except Exception:
        return False


def load_bvh() -> ModuleType | None:
    """The compiled BVH extension, or ``None`` (with one warning) when it cannot be built."""
    with _LOCK:
        if "bvh" in _STATE:
            return _STATE["bvh"]
        module: ModuleType | None
        try:
            from torch.utils.cpp_extension import load

            name = _module_name()
            module = _import_built(name)
            if module is not None:
                _STATE["bvh"] = module
                return module
            module = load(
                name=name,
                sources=[str(p) for p in _SOURCES],
                extra_cflags=_CFLAGS,
                extra_ldflags=["-fopenmp"],
                verbose=False,
            )
        except Exception as err:  # no compiler, no ninja, read-only cache, ...
            warnings.warn(
                f"torchmeshmetric: could not compile the C++ BVH extension ({type(err).__name__}: {err}); "
                "falling back to the exact pure-torch path, which is slower on the CPU.",
                RuntimeWarning,
                stacklevel=3,
            )
            module = None
        _STATE["bvh"] = module
        return module
