"""The one SHA-256 checksum of a cache entry's content: the registration cache's entries and the CTC campaign's records.

A cache entry holds this checksum of its content and is checked against it when read (docs/bad-input.md): a block
zeroed on a shared disk, a truncated copy or a hand edit is then found and the entry recomputed, never trusted.
Light on purpose (the standard library only): a tensor is fed by its bytes when torch is loaded, and no value can be
a tensor when it is not.
"""

from __future__ import annotations

import hashlib
import sys
from collections.abc import Mapping

__all__ = ["content_sha256"]


def _feed(h: hashlib._Hash, value: object) -> None:
    """Add ``value`` to ``h`` unambiguously.

    Each tensor by its dtype, shape and bytes, mappings by sorted key, sequences in order, the rest by type and
    ``repr`` (exact for floats).
    """
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(value, torch.Tensor):
        t = value.detach().to("cpu").contiguous()
        h.update(f"tensor {t.dtype} {tuple(t.shape)}\0".encode())
        h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes())
    elif isinstance(value, Mapping):
        h.update(f"mapping {len(value)}\0".encode())
        for key in sorted(value, key=str):
            h.update(f"{key!r}\0".encode())
            _feed(h, value[key])
    elif isinstance(value, (list, tuple)):
        h.update(f"sequence {len(value)}\0".encode())
        for item in value:
            _feed(h, item)
    else:
        h.update(f"{type(value).__name__} {value!r}\0".encode())


def content_sha256(payload: Mapping[str, object]) -> str:
    """The SHA-256 of an entry's content, stored in it as ``"sha256"`` and checked when it is read.

    Example:
        >>> content_sha256({"figures": {"GridD1": 61.5}}) == content_sha256({"figures": {"GridD1": 61.5}})
        True
        >>> content_sha256({"figures": {"GridD1": 61.5}}) == content_sha256({"figures": {"GridD1": 70.0}})
        False
    """
    h = hashlib.sha256()
    _feed(h, payload)
    return h.hexdigest()
