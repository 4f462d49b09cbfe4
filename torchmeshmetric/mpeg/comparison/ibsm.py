"""mmetric's image-based sampling metric (``compare --mode ibsm``, software renderer): render both meshes, compare.

Both meshes are reindexed (``reorder --sort oriented``, as mmetric does unless told not to) and rendered from
``cameras`` directions on a Fibonacci sphere by an orthographic camera fitted to the union of their bounding boxes
(radius = 1.01 x the half diagonal), into ``resolution x resolution`` colour and depth buffers, with back faces culled
and bilinear texture filtering. Only pixels covered in both renderings count; squared errors are pooled over all
cameras, one MSE per channel (R, G, B, and Y, U, V in BT.709 on 0..255, YUV = (6Y + U + V) / 8), PSNR =
``10 log10(255^2 / MSE)`` capped at 99.99; the geometric error is the depth difference rescaled to 255 by the depth
range. The rasterizer (``ibsm_raster.cpp``) does mmetric's float32 arithmetic in its order, so the buffers equal
mmetric's pixel for pixel; it runs the cameras in parallel on torch's CPU threads.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from types import ModuleType

import numpy as np
import torch

from torchmeshmetric import native
from torchmeshmetric._checks import SizeLimitError, check_allocation, check_flag, check_int
from torchmeshmetric.mpeg.core.reindex import oriented_reindex
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh

__all__ = ["MAX_IBSM_RESOLUTION", "IbsmNoOverlapWarning", "IbsmResult", "ibsm", "ibsm_render"]

#: The largest buffer side: ``ctc --ibsm-resolution`` and the campaign manifest's ``ibsm_resolution`` bound. A 32768²
#: rendering is 2**30 pixels, 8 GiB of depth and colour in mmetric's whole-image buffers (each rendering of
#: :func:`ibsm_render` too); the rasterizer's pixel coordinates are C ``int`` and float32, which a larger side would
#: first make inexact, then wrap (4294967360 = 2**32 + 64 rendered at 64 before review X).
MAX_IBSM_RESOLUTION = 1 << 15

# Bytes per pixel of a rendering: a float32 depth and 4 uint8 colour channels.
_PIXEL_BYTES = 8
# Rows of a band (ibsm_raster.cpp's BAND_ROWS): ibsm() holds two bands per thread, never a whole image.
_BAND_ROWS = 16


class IbsmNoOverlapWarning(UserWarning):
    """IBSM of two meshes with no pixel covered in both renderings: the 99.99 dB figures measure nothing.

    Example:
        >>> import torch, trimesh, warnings
        >>> from torchmeshmetric.structures import Mesh
        >>> s = trimesh.creation.icosphere(2)
        >>> m = TexturedMesh(Mesh(torch.tensor(s.vertices, dtype=torch.float32), torch.tensor(s.faces)))
        >>> far = TexturedMesh(Mesh(m.mesh.verts + torch.tensor([5.0, 0.0, 0.0]), m.mesh.faces))  # disjoint
        >>> with warnings.catch_warnings(record=True) as caught:
        ...     warnings.simplefilter("always")
        ...     r = ibsm(m, far, resolution=32, cameras=4)
        >>> [w.category.__name__ for w in caught], r.pixels
        (['IbsmNoOverlapWarning'], 0)
    """


def _rasterizer() -> ModuleType:
    """The compiled rasterizer (``native/ibsm_raster.cpp``); a clear error where it cannot be built."""
    try:
        return native.load("ibsm")
    except native.NativeBuildError as err:
        raise RuntimeError(f"ibsm: {err}; IBSM needs a C++ compiler and ninja") from err


@dataclass(frozen=True)
class IbsmResult:
    """mmetric's IBSM figures for one mesh pair.

    Attributes:
        rgb_mse: ``(R, G, B, RGB)`` MSE over the pixels covered in both renderings (RGB = mean of the three).
        yuv_mse: ``(Y, U, V, YUV)`` MSE (YUV = (6 Y + U + V) / 8).
        geo_mse: depth MSE, the depth difference rescaled to 255 by the depth range.
        rgb_psnr: PSNR of ``rgb_mse`` (``10 log10(255^2 / MSE)``, at most 99.99).
        yuv_psnr: PSNR of ``yuv_mse``.
        geo_psnr: PSNR of ``geo_mse``.
        unmatched_percent: pixels covered in one rendering only, in percent of those covered in both.
        box_ratio: 100 x the distorted mesh's box diagonal over the reference's.
        pixels: pixels covered in both renderings, over all cameras.

    Example:
        >>> import torch, trimesh
        >>> from torchmeshmetric.structures import Mesh
        >>> s = trimesh.creation.icosphere(2)
        >>> m = TexturedMesh(Mesh(torch.tensor(s.vertices, dtype=torch.float32), torch.tensor(s.faces)))
        >>> r = ibsm(m, m, resolution=64, cameras=4)
        >>> r.geo_psnr, r.rgb_psnr[3], r.unmatched_percent, r.box_ratio, r.pixels > 0
        (99.99, 99.99, 0.0, 100.0, True)
    """

    rgb_mse: tuple[float, float, float, float]
    yuv_mse: tuple[float, float, float, float]
    geo_mse: float
    rgb_psnr: tuple[float, float, float, float]
    yuv_psnr: tuple[float, float, float, float]
    geo_psnr: float
    unmatched_percent: float
    box_ratio: float
    pixels: int


def _psnr(mse: float) -> float:
    # mmetric's std::min(99.99, psnr): a zero MSE (inf) and a NaN one (no pixel covered in both renderings, 0 / 0)
    # both give 99.99; the second shows as unmatched_percent = 100 and pixels = 0
    if math.isnan(mse) or mse <= 0:
        return 99.99
    return min(99.99, 10.0 * math.log10(255.0 * 255.0 / mse))


def _arrays(m: TexturedMesh) -> tuple[torch.Tensor, ...]:
    """Contiguous CPU tensors (verts, faces, uvs, texture, colours) for the rasterizer; empty where absent."""
    v = m.mesh.verts.detach().to("cpu", torch.float32).contiguous()
    f = m.mesh.faces.detach().to("cpu", torch.int64).contiguous()
    empty_f = torch.zeros(0, dtype=torch.float32)
    if m.texture is not None and m.uvs is not None:
        uv = m.uvs.detach().to("cpu", torch.float32).contiguous()
        tex = np.asarray(m.texture)
        if tex.ndim == 2:
            tex = np.repeat(tex[..., None], 3, axis=2)
        # a copy: a texture read from a file is a read-only array, which torch would warn about
        tex_t = torch.from_numpy(np.array(tex[..., :3], dtype=np.uint8, order="C"))
        return v, f, uv, tex_t, empty_f
    col = empty_f if m.colors is None else m.colors.detach().to("cpu", torch.float32).contiguous()
    return v, f, empty_f, torch.zeros(0, dtype=torch.uint8), col


def _check(resolution: int, cameras: int) -> None:
    check_int(resolution, "resolution")
    if not 1 <= resolution <= MAX_IBSM_RESOLUTION:  # before the rasterizer sees it (its C++ refuses it too)
        error = SizeLimitError if resolution > MAX_IBSM_RESOLUTION else ValueError
        raise error(f"resolution: expected an integer in 1..{MAX_IBSM_RESOLUTION}, found {resolution!r}")
    check_int(cameras, "cameras", 2)  # mmetric's Fibonacci sphere needs 2 cameras


def _prepared(m: TexturedMesh, name: str, reorder: bool) -> TexturedMesh:
    if m.mesh.faces.shape[0] == 0:
        raise ValueError(f"{name}: expected a mesh with faces, found none (IBSM renders surfaces)")
    if not torch.isfinite(m.mesh.verts).all():
        raise ValueError(f"{name}: vertex positions hold NaN or Inf")
    return oriented_reindex(m) if reorder else m


def ibsm(
    ref: TexturedMesh,
    dis: TexturedMesh,
    *,
    resolution: int = 2048,
    cameras: int = 16,
    cull: bool = True,
    reorder: bool = True,
) -> IbsmResult:
    """The ``compare --mode ibsm`` of mmetric (software renderer, no camera rotation): ``dis`` against ``ref``.

    Args:
        ref: the reference mesh with its texture (or vertex colours; red without either, as mmetric).
        dis: the distorted mesh.
        resolution: the square buffers' side (``--ibsmResolution``, 2048).
        cameras: camera directions on the Fibonacci sphere (``--ibsmCameraCount``, 16).
        cull: back-face culling (mmetric's default; ``--ibsmDisableCulling`` turns it off).
        reorder: the oriented reindexing first (mmetric's default; ``--ibsmDisableReordering``).

    Returns:
        :class:`IbsmResult`.

    Raises:
        ValueError: a mesh without faces or with non-finite vertices, a bad resolution or camera count.
        SizeLimitError: ``resolution`` above :data:`MAX_IBSM_RESOLUTION` (a ``ValueError`` too).
        RuntimeError: the C++ rasterizer cannot be built.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.structures import Mesh
        >>> s = trimesh.creation.icosphere(2)
        >>> m = TexturedMesh(Mesh(torch.tensor(s.vertices, dtype=torch.float32), torch.tensor(s.faces)))
        >>> r = ibsm(m, m, resolution=64, cameras=4)
        >>> r.geo_psnr, r.unmatched_percent
        (99.99, 0.0)
    """
    cull = check_flag(cull, "cull")
    reorder = check_flag(reorder, "reorder")
    _check(resolution, cameras)
    # each thread's two bands of rows (the rasterizer's Target), before any is allocated
    bands = 2.0 * _BAND_ROWS * resolution * min(cameras, torch.get_num_threads())
    check_allocation(bands, _PIXEL_BYTES, "resolution", resolution, "pixels")
    check_allocation(float(cameras), 100, "cameras", cameras, "cameras")  # a direction and 11 sums each
    a, b = _prepared(ref, "ref", reorder), _prepared(dis, "dis", reorder)
    va, vb = a.mesh.verts.to(torch.float32), b.mesh.verts.to(torch.float32)
    amin, amax = va.min(0).values, va.max(0).values
    bmin, bmax = vb.min(0).values, vb.max(0).values
    box = torch.cat([torch.minimum(amin, bmin), torch.maximum(amax, bmax)]).contiguous()
    box_ratio = 100.0 * float(torch.linalg.vector_norm(bmax - bmin)) / float(torch.linalg.vector_norm(amax - amin))
    sums = _rasterizer().ibsm_sums(*_arrays(a), *_arrays(b), box, cameras, resolution, cull).numpy()
    # mmetric adds camera after camera into one float64 accumulator; the per-camera sums are added in that order
    acc = np.zeros(sums.shape[1])
    for row in sums:
        acc += row
    total = [float(x) for x in acc]
    n = total[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        rgb = [float(np.float64(total[2 + c]) / n) for c in range(3)]
        yuv = [float(np.float64(total[5 + c]) / n) for c in range(3)]
        geo = float(np.float64(total[8]) / n)
    rgb_mse = (rgb[0], rgb[1], rgb[2], (rgb[0] + rgb[1] + rgb[2]) / 3.0)
    yuv_mse = (yuv[0], yuv[1], yuv[2], (yuv[0] * 6.0 + yuv[1] + yuv[2]) / 8.0)
    if n == 0:  # mmetric's figure is kept (its 0 / 0 gives 99.99), but it says nothing about the pair
        warnings.warn(
            "ibsm: no pixel is covered in both renderings (the meshes never overlap on screen); the PSNRs are "
            "mmetric's 99.99 for this case, not a measure of similarity",
            IbsmNoOverlapWarning,
            stacklevel=2,
        )
    return IbsmResult(
        rgb_mse=rgb_mse,
        yuv_mse=yuv_mse,
        geo_mse=geo,
        rgb_psnr=tuple(_psnr(x) for x in rgb_mse),  # type: ignore[arg-type]
        yuv_psnr=tuple(_psnr(x) for x in yuv_mse),  # type: ignore[arg-type]
        geo_psnr=_psnr(geo),
        unmatched_percent=100.0 * total[1] / n if n > 0 else 100.0,
        box_ratio=box_ratio,
        pixels=int(n),
    )


def ibsm_render(
    mesh: TexturedMesh,
    direction: tuple[float, float, float],
    box: tuple[tuple[float, float, float], tuple[float, float, float]],
    *,
    resolution: int = 2048,
    cull: bool = True,
) -> tuple[torch.Tensor, torch.Tensor, float]:
    """One of IBSM's renderings: ``(depth (R, R) float32, RGBA (R, R, 4) uint8, depth range)``; row 0 is the bottom.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.structures import Mesh
        >>> s = trimesh.creation.icosphere(2)
        >>> m = TexturedMesh(Mesh(torch.tensor(s.vertices, dtype=torch.float32), torch.tensor(s.faces)))
        >>> z, rgba, rng = ibsm_render(m, (0, 0, 1), ((-1, -1, -1), (1, 1, 1)), resolution=32)
        >>> rgba.shape, rgba[16, 16].tolist(), rng
        (torch.Size([32, 32, 4]), [255, 0, 0, 255], 3.0)
    """
    cull = check_flag(cull, "cull")
    _check(resolution, 2)
    # the whole image, twice (the rasterizer's buffers, then the tensors returned), before any of it is allocated
    check_allocation(2.0 * resolution * resolution, _PIXEL_BYTES, "resolution", resolution, "pixels")
    b = torch.tensor([*box[0], *box[1]], dtype=torch.float32)
    d = torch.tensor(direction, dtype=torch.float32)
    z, c, rng = _rasterizer().ibsm_render(*_arrays(mesh), b, d, resolution, cull)
    return z, c, float(rng[0])
