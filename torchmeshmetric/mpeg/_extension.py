"""Just-in-time build of the MPEG C++ sources (IBSM's rasterizer, the pcc search), compiled once and cached by torch.

Each source is its own extension named after the hash of its text, so an edited source rebuilds instead of reusing a
stale build; a finished build of the exact source is imported directly, without ``load``'s ninja run and lock.
"""

from __future__ import annotations

import hashlib
import importlib.util
import threading
from pathlib import Path
from types import ModuleType

__all__ = ["ibsm_extension", "load_extension", "pcc_extension"]

IBSM_SOURCE = Path(__file__).with_name("ibsm_raster.cpp")
"""IBSM's software rasterizer, also grid sampling's ray caster."""
PCC_SOURCE = Path(__file__).parents[1] / "native" / "mpeg_pcc.cpp"
"""The pcc comparison's duplicate merge and neighbour search."""

_LOCK = threading.Lock()
_STATE: dict[Path, ModuleType] = {}
# -ffp-contract=off: no fused multiply-add, every float operation rounded as mmetric's compiled code rounds it
_CFLAGS = ["-O3", "-ffp-contract=off", "-fno-fast-math", "-std=c++17"]


def load_extension(source: Path, what: str) -> ModuleType:
    """The compiled extension of ``source`` (built once); a clear error naming ``what`` where it cannot be built.

    Args:
        source: the ``.cpp`` file.
        what: the feature that needs it, for the error message (``"ibsm"``, ``"pcc"``).

    Returns:
        The loaded module.

    Raises:
        RuntimeError: no C++ compiler or ``ninja``, or the build failed.

    Example:
        >>> load_extension(PCC_SOURCE, "pcc").mpeg_merge_order  # doctest: +ELLIPSIS
        <built-in method mpeg_merge_order ...>
    """
    with _LOCK:
        if source in _STATE:
            return _STATE[source]
        from torch.utils.cpp_extension import _get_build_directory, load

        name = f"torchmeshmetric_{source.stem}_" + hashlib.sha1(source.read_bytes()).hexdigest()[:10]
        built = Path(_get_build_directory(name, verbose=False)) / f"{name}.so"
        try:
            if built.is_file():
                spec = importlib.util.spec_from_file_location(name, built)
                assert spec is not None and spec.loader is not None
                module = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(module)
            else:
                module = load(name=name, sources=[str(source)], extra_cflags=_CFLAGS, verbose=False)
        except Exception as err:
            raise RuntimeError(
                f"{what}: the C++ extension could not be built ({type(err).__name__}: {err}); it needs a C++ "
                "compiler and ninja"
            ) from err
        _STATE[source] = module
        return module


def ibsm_extension() -> ModuleType:
    """The compiled rasterizer and ray caster (:data:`IBSM_SOURCE`)."""
    return load_extension(IBSM_SOURCE, "ibsm")


def pcc_extension() -> ModuleType:
    """The compiled merge and neighbour search (:data:`PCC_SOURCE`)."""
    return load_extension(PCC_SOURCE, "pcc")
