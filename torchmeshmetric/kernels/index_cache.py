"""``IndexCache``: one :class:`~torchmeshmetric.MeshIndex` per reference mesh, found again by content.

Loops that measure against the same references again and again (the frames of ``compare``, the validation set of a
training loop, every epoch) ask the cache instead of building: an index is keyed by a hash of the mesh's vertices
and faces (plus dtype, device, backend), so equal content finds the built structure even through new tensors.
The meshes a loss learns move at every step and would only push the references out: the cache keeps one index of
them apart (``moving``, a :class:`~torchmeshmetric.kernels.kept_index.KeptIndex`), refitted while their faces stay
the same.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Sequence

import torch

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
        h.update(v.detach().cpu().contiguous().numpy().tobytes())
        h.update(f.detach().to("cpu", torch.int64).contiguous().numpy().tobytes())
    return h.hexdigest()


class IndexCache:
    """Least-recently-used cache of :class:`~torchmeshmetric.MeshIndex` keyed by mesh content.

    Also holds, in ``moving``, the index of the simplified meshes a loss measures the reverse direction to
    (:class:`~torchmeshmetric.metrics.MeshSurfaceDistanceLoss` with ``two_sided=True``): their vertices move at every
    training step, so it is refitted while their faces stay the same and rebuilt when they change (one such index;
    its answers are those of a new index, bit for bit).

    Args:
        max_entries: indexes kept (the least recently used is dropped beyond).

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
        self.moving = KeptIndex()

    def get(self, mesh: MeshLike | Sequence[MeshLike], *, backend: str = "auto", tree: str = "sah") -> MeshIndex:
        """The index of ``mesh`` (a mesh-like or a list: a batch), built on the first request for this content.

        When the cached index was built from other tensors of equal content, the returned index shares its
        structure but recomputes distances from ``mesh``'s own vertices (so gradients reach them). The entry itself
        is built on copies the cache owns; the returned index refuses to answer (``StaleIndexError``) once
        ``mesh``'s tensors change in place: ask the cache again for the changed mesh. ``tree`` as in
        :class:`~torchmeshmetric.MeshIndex` (``"morton"`` for references queried only a few times).
        """
        batch = isinstance(mesh, list) or (isinstance(mesh, tuple) and not looks_like_pair(mesh))
        meshes = [as_mesh(m) for m in mesh] if batch else [as_mesh(mesh)]  # type: ignore[union-attr,arg-type]
        key = content_key(meshes, f"{backend}/{tree}")
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
        self.moving = KeptIndex()
