"""``KeptIndex``: the index of meshes whose vertices move between calls, refitted while their faces stay the same.

A training loop measures to the meshes it learns (a learned simplifier's output, the temporal loss's simplified
frames) at every step: their vertices move, their connectivity is usually fixed within a run. Rebuilding their
:class:`~torchmeshmetric.MeshIndex` at every step was about 45 % of a step of
:class:`~torchmeshmetric.metrics.MeshSurfaceDistanceLoss` (a 20k-face simplified mesh, one thread:
``tests/benchmarks/surface_loss_refit.py``); a refit rewrites the bounds only (0.3 ms there). The kernels are exact
(the closest face is the one of least computed squared distance, the lowest index among equal ones, whatever the
tree), so a refitted index answers what a new one would, bit for bit.

Never stale: the vertices are refitted to the call's own at every call (whatever happened to them in between, even
writes torch does not count); the faces are compared with a copy this object owns (the same tensor object at the
same in-place version is the same faces without reading them: on CUDA a comparison is a host-device sync), and the
index is built on that copy, so that nothing the caller later does to its tensors changes what the index holds.
Its one blind spot is that of every kept index (``docs/kernels.md``): faces rewritten in place by a write torch does
not count (``.data``, a shared numpy array) in the very tensor of the last call are taken for the same faces.
"""

from __future__ import annotations

import torch
from torch import Tensor

from torchmeshmetric.kernels.mesh_index import MeshIndex, _version
from torchmeshmetric.structures import Mesh

__all__ = ["KeptIndex"]


class KeptIndex:
    """One :class:`~torchmeshmetric.MeshIndex` of a batch of meshes, refitted while their faces stay the same.

    Holds the index, a copy of the faces it was built on, and the caller's face tensors of the last call with their
    in-place versions (no graph, no copy of the vertices). :meth:`get` refits the index to the meshes' vertices
    when their faces, vertex counts, dtype and device are those of the last call, and builds a new one otherwise.
    Pickled (and deep-copied) empty, as :class:`~torchmeshmetric.IndexCache` is.

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric import Mesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> mesh = Mesh(torch.tensor(sphere.vertices), torch.tensor(sphere.faces))
        >>> kept = KeptIndex()
        >>> index = kept.get([mesh], "auto")
        >>> kept.get([Mesh(mesh.verts * 2, mesh.faces)], "auto") is index  # moved vertices: refitted
        True
    """

    def __init__(self) -> None:
        self.index: MeshIndex | None = None
        self.faces: list[Tensor] | None = None  # the copies the index was built on
        # The caller's faces tensors of the last call and their versions: the same tensors, unmodified, are the same
        # faces without comparing values (a comparison reads a bool back from the device: a sync per mesh on CUDA).
        self.sources: list[tuple[Tensor, int]] = []
        self.num_verts: list[int] = []
        self.backend = ""

    def _same_faces(self, meshes: list[Mesh]) -> bool:
        if self.faces is None or len(self.faces) != len(meshes):
            return False
        if len(self.sources) == len(meshes) and all(
            t is m.faces and v >= 0 and v == _version(m.faces) for (t, v), m in zip(self.sources, meshes, strict=True)
        ):
            return True
        if not all(
            f.shape == m.faces.shape and f.device == m.faces.device for f, m in zip(self.faces, meshes, strict=True)
        ):
            return False
        # One device read for the whole batch.
        return bool(torch.stack([(f == m.faces).all() for f, m in zip(self.faces, meshes, strict=True)]).all())

    def get(self, meshes: list[Mesh], backend: str) -> MeshIndex:
        """The index of ``meshes``: the kept one refitted to their vertices, or a new one (then kept).

        Args:
            meshes: the ``B`` meshes (validated: finite vertices, faces in range), in the dtype and on the device the
                index must have; their vertices may require grad (the index holds them detached).
            backend: the backend of a new index.

        Returns:
            The :class:`~torchmeshmetric.MeshIndex` of the meshes (detached vertices, packed in order; default tree),
            whose answers are those of ``MeshIndex(meshes, backend=backend)``, bit for bit.
        """
        verts = (meshes[0].verts if len(meshes) == 1 else torch.cat([m.verts for m in meshes])).detach()
        same = (
            self.index is not None
            and self.backend == backend
            and self.index.dtype == verts.dtype
            and self.index.device == verts.device
            and self.num_verts == [m.num_verts for m in meshes]
            and self._same_faces(meshes)
        )
        if same and self.index is not None:
            self.index.refit_unchecked(verts)  # validated by the caller
        else:
            # Built on copies of the faces: the index watches tensors nobody else writes to, and they are what the
            # next call's faces are compared with (built on the caller's faces, a refit after an in-place edit that
            # left them equal refused with StaleIndexError: found while moving this class out of the temporal loss).
            self.faces = [m.faces.clone() for m in meshes]
            built = [Mesh(m.verts.detach(), f, validate=False) for m, f in zip(meshes, self.faces, strict=True)]
            self.index = MeshIndex(built if len(built) > 1 else built[0], backend=backend)
            self.num_verts = [m.num_verts for m in meshes]
            self.backend = backend
        self.sources = [(m.faces, _version(m.faces)) for m in meshes]
        return self.index

    def __getstate__(self) -> dict[str, object]:
        # Kept between calls only: pickled empty (a module holding one is deep-copied and pickled by checkpoints).
        return KeptIndex().__dict__
