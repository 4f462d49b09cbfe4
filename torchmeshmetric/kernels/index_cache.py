"""``IndexCache``: one :class:`~torchmeshmetric.MeshIndex` per reference mesh, found again by content.

Loops that measure against the same references again and again (the frames of ``compare``, the validation set of a
training loop, every epoch) ask the cache instead of building: an index is keyed by a hash of the mesh's vertices
and faces (plus dtype, device, backend), so equal content finds the built structure even through new tensors.
The meshes a loss learns move at every step and would only push the references out: the cache keeps one index of
them apart (``moving``, a :class:`~torchmeshmetric.kernels.kept_index.KeptIndex`), refitted while their faces stay
the same.

The hash reads every vertex and face (a host copy: on CUDA a device-to-host copy of the whole mesh and a sync), and
a training loop asks for the same reference tensors at every step: about 10 % of a two-sided
``NearestVertexDistanceLoss`` step (0.84 ms of CPU time of 9.4 ms at the demo's resolution 160, one thread:
``tests/benchmarks/index_cache_memo.py``). So the cache remembers, for the last tensors it hashed, the key it found,
and gives it again without reading them while torch vouches that they hold the same values: the same tensor objects
(weak references: a freed tensor whose ``id`` is reused finds nothing), at the same in-place version counter, data
pointer, offset, shape, strides, dtype and device (:func:`_write_stamp`). Torch raises the counter at every in-place
write it dispatches (through views, ``detach()``, ``no_grad``, an optimizer's default step); the writes it does not
count are excluded where they can be seen and are the documented blind spot of every kept index
(``docs/kernels.md``) where they cannot:

* memory torch shares with another owner is never trusted (hashed at every call, as before): a tensor made from a
  numpy array (``torch.from_numpy``, ``torch.as_tensor``, ``Mesh`` of numpy arrays), one whose memory was handed to
  numpy (``t.numpy()``, ``np.asarray(t)``: torch marks the storage not resizable), DLPack imports, ``frombuffer``,
  ``torch.load`` and memory-mapped storages (all not resizable), CPU shared memory (``share_memory_()``, a
  ``DataLoader`` worker's tensors: another process may write there); inference tensors (no counter); and vertices
  that require grad (a trained reference: ``fused=True`` optimizers and ``p.data`` updates write without counting,
  and its values change at every step anyway);
* what remains unseen is a write torch does not count into memory torch allocated and has not handed to numpy:
  through ``.data`` of a tensor that does not require grad, a DLPack export (``np.from_dlpack(t)``, CuPy), a raw
  pointer (ctypes, a custom kernel writing in place), another process through CUDA IPC. The index the cache hands out
  already trusts the counters for these tensors (its ``StaleIndexError`` check), as do ``KeptIndex`` for faces across
  steps and ``Mesh``'s derived values; before, the next call's hash found the changed content, now it does not: after
  such a write, ask with new tensors (``t.clone()``) or a new cache. No O(1) rule sees these writes (they change
  nothing torch can read without reading the values, the very cost removed: on CUDA a sync).

The losses detach their references at every step; :meth:`~torchmeshmetric.Mesh.detach` keeps a mesh whose vertices
do not require grad (a detached alias would be a new tensor object at every step, never recognised).
"""

from __future__ import annotations

import ctypes
import hashlib
import weakref
from collections import OrderedDict
from collections.abc import Sequence

import torch
from torch import Tensor

from torchmeshmetric._checks import check_int
from torchmeshmetric.kernels._common import DEFAULT_MAX_MEMORY
from torchmeshmetric.kernels.kept_index import KeptIndex
from torchmeshmetric.kernels.mesh_index import MeshIndex, _given_tensors
from torchmeshmetric.structures import Mesh, MeshLike, as_mesh, looks_like_pair, pack_meshes

__all__ = ["IndexCache", "content_key"]


def content_key(meshes: Sequence[Mesh], salt: str) -> str:
    """A hash of the meshes' content (shapes, dtype, device, vertex and face values) and ``salt``.

    The key of an :class:`IndexCache` entry (``salt``: backend and tree), and of any cache of results computed
    from meshes (``salt``: the settings of the computation).

    Args:
        meshes: the meshes, in order.
        salt: what else the cached result depends on.

    Returns:
        40 hexadecimal digits; equal content and salt give equal keys, through new tensors too.

    Example:
        >>> import torch
        >>> from torchmeshmetric import Mesh
        >>> m = Mesh(torch.eye(3), torch.tensor([[0, 1, 2]]))
        >>> content_key([m], "a") == content_key([Mesh(torch.eye(3), torch.tensor([[0, 1, 2]]))], "a")
        True
    """
    h = hashlib.blake2b(digest_size=20)
    h.update(salt.encode())
    for m in meshes:
        v, f = m.verts, m.faces
        h.update(repr((tuple(v.shape), tuple(f.shape), str(v.dtype), str(v.device))).encode())
        for host in (v.detach().cpu().contiguous(), f.detach().to("cpu", torch.int64).contiguous()):
            h.update(_bytes_in_place(host))
    return h.hexdigest()


def _bytes_in_place(t: Tensor) -> memoryview:
    """The bytes of the contiguous CPU tensor ``t`` (kept alive by the caller while they are read), not copied.

    Not through ``t.numpy()``: that marks the storage as shared with numpy (not resizable), so the caller's tensor
    could no longer be ``resize_``d and the cache would take it for memory torch does not own (:func:`_write_stamp`)
    after its first hash; ``tobytes()`` also copied the mesh once more.
    """
    size = t.numel() * t.element_size()
    if size == 0:
        return memoryview(b"")
    return memoryview((ctypes.c_char * size).from_address(t.data_ptr())).cast("B")


_Stamp = tuple[int, int, int, tuple[int, ...], tuple[int, ...], torch.dtype, torch.device]
"""Stands for a tensor's values, unread: its version, data pointer, offset, shape, strides, dtype, device."""


def _write_stamp(t: Tensor) -> _Stamp | None:
    """``t``'s stamp while torch counts every write to its memory it can; ``None`` where it cannot vouch.

    Equal stamps of the same tensor object mean the same values unless something wrote to its memory without torch
    counting it (the module docstring lists what is refused here and what stays unseen). O(1): no value is read.

    Args:
        t: a vertex or face tensor.

    Returns:
        The stamp, or ``None`` for an inference tensor, a tensor that requires grad, or one whose storage torch
        shares with another owner (not resizable: numpy, DLPack, ``frombuffer``, ``torch.load``, mmap; or CPU
        shared memory).

    Example:
        >>> import numpy as np, torch
        >>> _write_stamp(torch.zeros(2, 3)) is None, _write_stamp(torch.from_numpy(np.zeros((2, 3)))) is None
        (False, True)
    """
    if t.is_inference() or t.requires_grad:
        return None
    storage = t.untyped_storage()
    # Not resizable: memory from (or handed to) another owner, e.g. numpy. `is_shared` is true of every CUDA storage
    # (cross-process sharing there is the CUDA IPC of the blind spot), so it says something on the CPU only.
    if not storage.resizable() or (t.device.type == "cpu" and storage.is_shared()):
        return None
    return (t._version, t.data_ptr(), int(t.storage_offset()), tuple(t.shape), t.stride(), t.dtype, t.device)


class IndexCache:
    """Least-recently-used cache of :class:`~torchmeshmetric.MeshIndex` keyed by mesh content.

    Also holds, in ``moving``, the index of the simplified meshes a loss measures the reverse direction to
    (:class:`~torchmeshmetric.metrics.MeshSurfaceDistanceLoss` with ``two_sided=True``): their vertices move at every
    training step, so it is refitted while their faces stay the same and rebuilt when they change (one such index;
    its answers are those of a new index, bit for bit).

    The key of the last ``max_entries`` tensor sets hashed is remembered while their tensors are unchanged (the
    module docstring), so a training loop that gives the same reference tensors at every step hashes them once.

    Args:
        max_entries: indexes kept (the least recently used is dropped beyond); also the number of remembered keys.

    Example:
        >>> import torch, trimesh
        >>> cache = IndexCache()
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> a = cache.get(sphere)
        >>> b = cache.get(sphere.copy())  # same content, new object: found again, nothing rebuilt
        >>> len(cache), b.num_items
        (1, 1)
    """

    def __init__(self, max_entries: int = 16) -> None:
        # an int >= 1: a string failed with a raw comparison error, 2.5 and True were taken (found by review)
        self.max_entries = check_int(max_entries, "max_entries", low=1)
        self._entries: OrderedDict[str, MeshIndex] = OrderedDict()
        self._init_known()
        self.moving = KeptIndex()

    def _init_known(self) -> None:
        # The key last found for given tensors (by salt and ids): their weak references and stamps, most recent last.
        self._known: OrderedDict[tuple[object, ...], tuple[str, tuple[tuple[weakref.ref[Tensor], _Stamp], ...]]]
        self._known = OrderedDict()

    def _key(self, meshes: list[Mesh], salt: str) -> str:
        """The content key of ``meshes``: remembered for the same unchanged tensors, else :func:`content_key`."""
        tensors = [t for m in meshes for t in (m.verts, m.faces)]
        stamps = [s for s in map(_write_stamp, tensors) if s is not None]
        if len(stamps) < len(tensors):  # one tensor torch cannot vouch for: read them all, as before
            return content_key(meshes, salt)
        ident = (salt, *(id(t) for t in tensors))
        known = self._known.get(ident)
        if (
            known is not None
            and known[0] in self._entries  # evicted: hashed again, as for any mesh the cache does not hold
            and all(r() is t and s == stamp for (r, s), t, stamp in zip(known[1], tensors, stamps, strict=True))
        ):
            self._known.move_to_end(ident)
            return known[0]
        key = content_key(meshes, salt)
        self._known[ident] = (key, tuple((weakref.ref(t), s) for t, s in zip(tensors, stamps, strict=True)))
        self._known.move_to_end(ident)
        if len(self._known) > self.max_entries:
            self._known.popitem(last=False)
        return key

    def get(self, mesh: MeshLike | Sequence[MeshLike], *, backend: str = "auto", tree: str = "sah") -> MeshIndex:
        """The index of ``mesh`` (a mesh-like or a list: a batch), built on the first request for this content.

        When the cached index was built from other tensors of equal content, the returned index shares its
        structure but recomputes distances from ``mesh``'s own vertices (so gradients reach them). The entry itself
        is built on copies the cache owns; the returned index refuses to answer (``StaleIndexError``) once
        ``mesh``'s tensors change in place: ask the cache again for the changed mesh. ``tree`` as in
        :class:`~torchmeshmetric.MeshIndex` (``"morton"`` for references queried only a few times).

        The content is hashed (:func:`content_key`) unless these very tensors were hashed before and torch vouches
        that they have not been written to since (the module docstring: what it vouches for and its blind spot);
        then the remembered key is used without reading them (on CUDA: no copy to the host, no sync).
        """
        batch = isinstance(mesh, list) or (isinstance(mesh, tuple) and not looks_like_pair(mesh))
        meshes = [as_mesh(m) for m in mesh] if batch else [as_mesh(mesh)]  # type: ignore[union-attr,arg-type]
        key = self._key(meshes, f"{backend}/{tree}")
        index = self._entries.get(key)
        if index is None:
            # Built on copies of its own (packing copies), so the entry answers for the content it is keyed by even
            # when the caller's tensors change later; each caller gets a copy that watches the caller's tensors.
            packed = pack_meshes(meshes if batch else meshes[0])
            index = MeshIndex.from_packed(packed, backend, DEFAULT_MAX_MEMORY, tree)
            self._entries[key] = index
            if len(self._entries) > self.max_entries:
                self._entries.popitem(last=False)
        else:
            self._entries.move_to_end(key)
        verts_given, faces_given = _given_tensors(mesh, None)
        if len(meshes) == 1:
            return index.with_verts_unchecked(meshes[0].verts, verts_given, faces_given)
        if any(m.verts.requires_grad for m in meshes):
            return index.with_verts_unchecked(torch.cat([m.verts for m in meshes]), verts_given, faces_given)
        return index.with_verts_unchecked(None, verts_given, faces_given)

    def __len__(self) -> int:
        return len(self._entries)

    def __getstate__(self) -> dict[str, object]:
        # A cache: pickled empty (a metric holding one is pickled, deep-copied and synced across processes).
        # `moving` is left out: pickles stay those of the versions before it.
        return {"max_entries": self.max_entries, "_entries": OrderedDict()}

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)
        self._init_known()
        self.moving = KeptIndex()
