"""Typed input checks shared by the whole library.

Every check raises an error that names the argument, what was found and what was expected, e.g.
``ShapeError: points: expected shape (P, 3), found (10, 2)``. The error classes subclass the built-in
``ValueError`` / ``TypeError`` so callers that already catch those keep working.
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Sequence

import torch
from torch import Tensor

__all__ = [
    "DeviceError",
    "DoubleBackwardError",
    "DTypeError",
    "EmptyInputError",
    "IndexRangeError",
    "NonFiniteError",
    "ShapeError",
    "SizeLimitError",
    "StaleIndexError",
    "all_finite",
    "available_memory",
    "check_allocation",
    "check_device",
    "check_finite",
    "check_float",
    "check_float_dtype",
    "check_has_values",
    "check_lengths",
    "check_non_empty",
    "check_positive_real",
    "check_real",
    "check_rgb255",
    "check_same_device",
    "check_shape",
    "check_tensor",
    "check_faces",
    "check_index_dtype",
    "common_dtype",
]


class ShapeError(ValueError):
    """A tensor has the wrong number of dimensions or the wrong size along one of them.

    Example:
        >>> import torch
        >>> from torchmeshmetric import Mesh
        >>> try:
        ...     Mesh(torch.zeros(3, 2), torch.tensor([[0, 1, 2]]))
        ... except ShapeError as error:  # a ValueError too
        ...     print(error)
        verts: expected shape (V, 3), found (3, 2)
    """


class DoubleBackwardError(RuntimeError):
    """A second derivative was asked of an operation that is differentiable once only (e.g. Danskin's gradient).

    Example:
        >>> import torch
        >>> from torchmeshmetric import mesh_surface_distance_loss
        >>> triangle = (torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> points = torch.tensor([[0.2, 0.2, 1.0]], requires_grad=True)
        >>> loss = mesh_surface_distance_loss(points, triangle)
        >>> try:
        ...     torch.autograd.grad(loss, points, create_graph=True)  # a Hessian-vector product would need this
        ... except DoubleBackwardError as error:  # a RuntimeError too
        ...     print(str(error).split(":")[1].strip())
        first-order only
        >>> torch.autograd.grad(mesh_surface_distance_loss(points, triangle), points)[0].tolist()  # once is fine
        [[0.0, 0.0, 1.0]]
    """


class DTypeError(TypeError):
    """A tensor has an unsupported dtype (e.g. integer coordinates or floating-point face indices).

    Example:
        >>> import torch
        >>> from torchmeshmetric import Mesh
        >>> try:
        ...     Mesh(torch.zeros(3, 3, dtype=torch.long), torch.tensor([[0, 1, 2]]))
        ... except DTypeError as error:  # a TypeError too
        ...     print(str(error).split(";")[0])
        verts: expected a floating-point tensor (float32 or float64), found dtype torch.int64
    """


class DeviceError(ValueError):
    """Tensors that must live on one device live on several.

    Also raised for a tensor on the ``meta`` device, which holds no values.

    Example:
        >>> import torch
        >>> from torchmeshmetric import Mesh
        >>> try:
        ...     Mesh(torch.zeros(3, 3), torch.tensor([[0, 1, 2]], device="meta"))
        ... except DeviceError as error:  # a ValueError too
        ...     print(str(error).split(",")[0])
        faces: expected a tensor with values (on the CPU or a GPU)
    """


class NonFiniteError(ValueError):
    """A tensor holds NaN or Inf where only finite values make sense.

    Example:
        >>> import torch
        >>> from torchmeshmetric import Mesh
        >>> try:
        ...     Mesh(torch.tensor([[float("nan"), 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        ... except NonFiniteError as error:  # a ValueError too
        ...     print(error)
        verts: expected finite values, found 1 NaN/Inf value(s)
    """


class IndexRangeError(ValueError):
    """Indices (face corners, lengths) point outside the array they index.

    Example:
        >>> import torch
        >>> from torchmeshmetric import Mesh
        >>> try:
        ...     Mesh(torch.zeros(3, 3), torch.tensor([[0, 1, 3]]))  # 3 vertices: rows 0 to 2
        ... except IndexRangeError as error:  # a ValueError too
        ...     print(error)
        faces: expected vertex indices in [0, 2], found values in [0, 3]
    """


class EmptyInputError(ValueError):
    """A mesh or point set is empty where at least one element is required.

    Example:
        >>> import torch
        >>> from torchmeshmetric import Mesh, point_mesh_distance
        >>> triangle = Mesh(torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]]))
        >>> try:
        ...     point_mesh_distance(torch.zeros(0, 3), triangle)
        ... except EmptyInputError as error:  # a ValueError too
        ...     print(error)
        points: expected at least one point, found an empty point set
    """


class SizeLimitError(ValueError):
    """A parameter asks for a result that cannot exist here: more elements than this machine's memory holds."""


class StaleIndexError(ValueError):
    """A kept index is queried after a tensor it was built from changed in place (refit it, or build a new one).

    Example:
        >>> import torch
        >>> from torchmeshmetric import MeshIndex
        >>> verts, faces = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), torch.tensor([[0, 1, 2]])
        >>> index = MeshIndex(verts, faces)
        >>> verts[:, 2] = 1.0  # the triangle lifted to z = 1 in place: the index still holds the old one
        >>> try:
        ...     index.point_mesh_distance(torch.tensor([[0.2, 0.2, 1.0]]))
        ... except StaleIndexError as error:  # a ValueError too
        ...     print(str(error).split(" (")[0])
        verts: modified in place since the index was built or last refitted
        >>> index.refit(verts)
        >>> index.point_mesh_distance(torch.tensor([[0.2, 0.2, 1.0]])).dists.tolist()  # on the lifted triangle
        [0.0]
    """


def _fmt_shape(shape: Sequence[int | str]) -> str:
    return "(" + ", ".join(str(s) for s in shape) + ")"


def check_tensor(x: object, name: str, expected: str = "a torch.Tensor") -> None:
    """Require a ``torch.Tensor``; the error names what was found and, for a numpy array, the conversion.

    A numpy array is not a tensor here, and where a list of point sets is accepted too it was taken as one (each
    row a "point set" of shape ``(3,)``): the error says so before anything is read from it.

    Args:
        x: the argument.
        name: its name in the error.
        expected: what was expected, e.g. ``"a (P, 3) torch.Tensor or a list of them"``.

    Raises:
        TypeError: ``x`` is not a tensor.

    Example:
        >>> import numpy as np
        >>> check_tensor(np.zeros((5, 3)), "points")
        Traceback (most recent call last):
        ...
        TypeError: points: expected a torch.Tensor, found numpy.ndarray; convert it with torch.as_tensor(points)
    """
    if isinstance(x, Tensor):
        return
    import numpy as np  # loaded with torch already

    if isinstance(x, np.ndarray):
        found = "numpy.ndarray" if type(x) is np.ndarray else f"{type(x).__name__} (a numpy.ndarray)"
        raise TypeError(f"{name}: expected {expected}, found {found}; convert it with torch.as_tensor({name})")
    raise TypeError(f"{name}: expected {expected}, found {type(x).__name__}")


def check_shape(x: Tensor, pattern: Sequence[str | int], name: str) -> None:
    """Check ``x`` against a pattern such as ``("P", 3)``: strings are free sizes, integers fixed ones.

    Raises:
        TypeError: ``x`` is not a tensor.
        ShapeError: the number of dimensions or a fixed size differs.
    """
    check_tensor(x, name)
    expected = _fmt_shape([str(p) for p in pattern])
    if x.dim() != len(pattern) or any(isinstance(p, int) and s != p for s, p in zip(x.shape, pattern, strict=False)):
        raise ShapeError(f"{name}: expected shape {expected}, found {_fmt_shape(x.shape)}")


def check_float(x: Tensor, name: str) -> None:
    """Require float32 or float64 coordinates.

    Half precision (float16, bfloat16) is refused with a typed error on every entry point and every backend: its
    3 significant digits cannot give exact distances, and float16 overflows at squared distances above 65504. The
    caller converts (``x.float()``), which keeps the gradient flowing back to the half-precision tensor.
    """
    if x.dtype in (torch.float16, torch.bfloat16):
        raise DTypeError(
            f"{name}: expected float32 or float64, found dtype {x.dtype}; half precision cannot hold exact distances "
            "(convert with .float(): the gradient still reaches the half-precision tensor)"
        )
    if x.is_complex():
        raise DTypeError(
            f"{name}: expected a real floating-point tensor (float32 or float64), found dtype {x.dtype}; "
            "complex coordinates have no distance here (take .real if the imaginary parts are zero)"
        )
    if not x.is_floating_point():
        kind = "boolean" if x.dtype == torch.bool else "integer"  # the advice names what was found
        raise DTypeError(
            f"{name}: expected a floating-point tensor (float32 or float64), found dtype {x.dtype}; "
            f"convert {kind} coordinates with .float() or .double()"
        )


def common_dtype(*dtypes: torch.dtype) -> torch.dtype:
    """The dtype a computation on inputs of ``dtypes`` runs in and answers in: torch's type promotion.

    The library's one dtype rule (``docs/concepts.md``, *Precision*): a distance between float32 and float64
    geometry is computed and returned in float64, whichever side is which, so that no input is rounded; autograd
    casts each input's gradient back to that input's own dtype (a float32 model gets float32 gradients).

    Args:
        dtypes: the floating dtypes of every geometric input (points, vertices, a prebuilt index's).

    Returns:
        Their promotion (``torch.promote_types`` of all), e.g. float64 for ``(float32, float64)``.

    Example:
        >>> common_dtype(torch.float32, torch.float64, torch.float32)
        torch.float64
    """
    return functools.reduce(torch.promote_types, dtypes)


def check_index_dtype(index_dtype: torch.dtype, dtype: torch.dtype, name: str) -> None:
    """Refuse a prebuilt index narrower than the dtype its queries are computed in (:func:`common_dtype`).

    An index answers in its own dtype: narrower queries are cast up to it (exactly), wider ones would be rounded
    down to it, which the dtype rule never does. Converting the index instead would rebuild its whole structure
    (about the cost of the queries it was built to save) behind the caller's back, at every call or refit; the
    error says how to build it once in the right dtype.

    Raises:
        DTypeError: ``index_dtype`` cannot hold ``dtype`` values exactly.
    """
    if torch.promote_types(index_dtype, dtype) != index_dtype:
        raise DTypeError(
            f"{name}: expected an index of dtype {dtype} (the promoted dtype of its queries), found one of dtype "
            f"{index_dtype}, which would round them; build the index once in {dtype} "
            f"(MeshIndex(mesh.to(dtype={dtype}))), or give every input in {index_dtype}"
        )


def all_finite(x: Tensor) -> bool:
    """Whether every value of ``x`` is finite (no NaN, no Inf).

    A sum is finite only if all its terms are (NaN and Inf propagate through it), and one reduction costs a tenth of
    the elementwise ``isfinite``; only a non-finite sum (a NaN or Inf term, or finite terms whose sum overflows) is
    decided elementwise.
    """
    x = x.detach()
    return bool(torch.isfinite(x.sum())) or bool(torch.isfinite(x).all())


def check_finite(x: Tensor, name: str) -> None:
    """Require every value of ``x`` to be finite (no NaN, no Inf), and values to check (not a meta tensor)."""
    check_has_values(x, name)
    if x.numel() and not all_finite(x):
        n_bad = int((~torch.isfinite(x)).sum())
        raise NonFiniteError(f"{name}: expected finite values, found {n_bad} NaN/Inf value(s)")


def check_flag(value: object, name: str) -> bool:
    """Require a bool: ``"no"`` or ``1`` taken for ``True`` turned a two-sided loss on, a gradient off, in silence.

    Example:
        >>> check_flag(False, "two_sided")
        False
    """
    if isinstance(value, bool):
        return value
    import numpy as np  # loaded with torch already

    if isinstance(value, np.bool_) or (isinstance(value, Tensor) and value.dtype == torch.bool and value.numel() == 1):
        return bool(value)  # numpy's and torch's booleans are booleans too
    raise TypeError(f"{name}: expected a bool, found {type(value).__name__} {value!r}")


def check_int(value: object, name: str, low: int | None = None) -> int:
    """Require an int (not a bool, not a float that ``int()`` would truncate), at least ``low`` when given.

    Example:
        >>> check_int(3, "seed")
        3
    """
    if isinstance(value, Tensor) and value.numel() == 1 and not (value.is_floating_point() or value.is_complex()):
        value = value.item() if value.dtype != torch.bool else value  # a one-element integer tensor is an int
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):  # numpy's integers are Integral
        raise TypeError(f"{name}: expected an int, found {type(value).__name__} {value!r}")
    if low is not None and value < low:
        raise ValueError(f"{name}: expected an int >= {low}, found {value!r}")
    return int(value)


def check_seed(value: object, name: str = "seed") -> int:
    """Require a seed torch's generators take: an int (:func:`check_int`'s) in ``[-2**63, 2**64)``.

    A seed outside that range reached ``Generator.manual_seed`` and failed there with torch's untyped
    ``ValueError: Overflow when unpacking long long``, naming no argument (found by review).

    Example:
        >>> check_seed(2**70)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        ValueError: seed: expected an int in [-2**63, 2**64) (torch's seed range), found 1180591620717411303424
    """
    seed = check_int(value, name)
    if not -(2**63) <= seed < 2**64:
        raise ValueError(f"{name}: expected an int in [-2**63, 2**64) (torch's seed range), found {seed}")
    return seed


def check_generator(value: object, name: str = "generator") -> torch.Generator | None:
    """Require ``None`` or a ``torch.Generator``: a seed passed in its place failed in torch's sampler.

    ``sample_surface(..., generator=0)`` raised torch's ``rand() received an invalid combination of arguments``
    (found by review); the message says to seed a generator.

    Example:
        >>> check_generator(0)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        TypeError: generator: expected a torch.Generator or None, found int 0 (for a seed, pass ...)
    """
    if value is None or isinstance(value, torch.Generator):
        return value
    raise TypeError(
        f"{name}: expected a torch.Generator or None, found {type(value).__name__} {value!r} (for a seed, pass "
        "torch.Generator().manual_seed(seed))"
    )


def as_real(value: object, name: str) -> float | None:
    """``value`` as a float when it is a real number, else ``None``: the one definition of a number for every option.

    A Python or numpy int or float, or a one-element real tensor; not a bool (``True`` is no weight or power), not a
    complex. Numeric options that refuse with their own words (``power``, ``frame_weight``) call this, the others
    :func:`check_real`: ``np.float32(2.0)`` and ``torch.tensor(0.5)`` were refused by some options as "not a finite
    number" though the docs call them numbers "as for every numeric option" (found by review).

    Example:
        >>> import numpy as np
        >>> as_real(np.float32(0.5), "power"), as_real(torch.tensor(2.0), "power"), as_real(True, "power")
        (0.5, 2.0, None)
    """
    if isinstance(value, Tensor) and value.numel() == 1 and value.dtype != torch.bool and not value.is_complex():
        check_has_values(value, name)
        return float(value.item())
    if isinstance(value, bool) or not isinstance(value, numbers.Real):  # numpy's floats and ints are Real
        return None
    return float(value)


def check_real(value: object, name: str) -> float:
    """Require a real number: a Python or numpy int or float, or a one-element real tensor (not a bool), as a float.

    A one-element tensor is a number here as it is for :func:`check_int`: ``mpeg_pcqm(radius_curvature=
    torch.tensor(0.05))`` was refused as "not a positive finite number" (found by review).

    Example:
        >>> import numpy as np
        >>> check_real(np.float32(0.5), "dt")
        0.5
        >>> check_real(torch.tensor(0.25), "dt")
        0.25
    """
    x = as_real(value, name)
    if x is None:
        raise TypeError(f"{name}: expected a float, found {type(value).__name__} {value!r}")
    return x


def check_positive_real(value: object, name: str) -> float:
    """Require a finite real number > 0 (:func:`check_real`'s numbers), returned as a float.

    Example:
        >>> check_positive_real(2, "radius_factor")
        2.0
        >>> check_positive_real(float("nan"), "peak")
        Traceback (most recent call last):
        ...
        ValueError: peak: expected a positive finite number, found nan
    """
    x = check_real(value, name)
    if not (math.isfinite(x) and x > 0):
        raise ValueError(f"{name}: expected a positive finite number, found {x!r}")
    return x


def check_rgb255(colors: Tensor, name: str) -> None:
    """Require RGB colours on mmetric's 8-bit scale: values in ``[0, 255]``, not all fractions of ``[0, 1]``.

    mmetric reads 8-bit colours, so it never sees other values; given them, the library rounded or truncated them
    in silence: colours normalised to ``[0, 1]`` (torch's convention) became black and hid every colour distortion,
    negative ones extrapolated PCQM's lightness table (found by review). NaN is left to the caller's own rule (the
    pcc merge counts it as 0, as mmetric's conversion does; PCQM refuses it).

    Raises:
        ValueError: naming ``name`` and the range found.

    Example:
        >>> check_rgb255(torch.tensor([[0.2, 0.5, 1.0]]), "ref.colors")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        ValueError: ref.colors: expected 8-bit RGB values in [0, 255], found fractions in [0.2, 1] ...
    """
    check_has_values(colors, name)
    c = colors.detach().to(torch.float64)
    c = c[~torch.isnan(c)]
    if c.numel() == 0:
        return
    lo, hi = (float(v) for v in torch.stack(torch.aminmax(c)).tolist())
    if lo < 0 or hi > 255:
        raise ValueError(f"{name}: expected 8-bit RGB values in [0, 255], found values in [{lo:g}, {hi:g}]")
    if hi <= 1 and bool((c != torch.round(c)).any()):
        raise ValueError(
            f"{name}: expected 8-bit RGB values in [0, 255], found fractions in [{lo:g}, {hi:g}] (colours normalised "
            "to [0, 1]? they would all round to black: multiply them by 255)"
        )


def check_non_empty(x: Tensor, name: str) -> None:
    """Require at least one row."""
    if x.shape[0] == 0:
        raise EmptyInputError(
            f"{name}: expected at least one element, found an empty tensor of shape {_fmt_shape(x.shape)}"
        )


def check_same_device(name_to_tensor: dict[str, Tensor]) -> None:
    """Require all tensors to live on one device."""
    devices = {n: t.device for n, t in name_to_tensor.items()}
    if len(set(devices.values())) > 1:
        found = ", ".join(f"{n} on {d}" for n, d in devices.items())
        raise DeviceError(f"expected all inputs on one device, found {found}")


def check_has_values(x: Tensor, name: str) -> None:
    """Refuse a meta tensor, which has a shape and no values.

    Every check of values failed on one with torch's untyped ``RuntimeError: Tensor.item() cannot be called on meta
    tensors`` (found by review).

    Raises:
        DeviceError: naming ``name``.
    """
    if x.is_meta:
        raise DeviceError(
            f"{name}: expected a tensor with values (on the CPU or a GPU), found one on the meta device, which holds "
            "shapes only"
        )


def check_faces(faces: Tensor, num_verts: int, name: str = "faces") -> None:
    """Require an integer ``(F, 3)`` tensor whose entries index ``num_verts`` vertices.

    Any integer dtype, signed or unsigned (glTF index buffers and plyfile's ``uint`` lists are uint16/uint32); the
    caller converts to int64 (``faces.long()``).
    """
    check_shape(faces, ("F", 3), name)
    if faces.is_floating_point() or faces.dtype == torch.bool or faces.is_complex():
        raise DTypeError(f"{name}: expected an integer tensor of vertex indices, found dtype {faces.dtype}")
    check_has_values(faces, name)
    if faces.numel():
        # torch has no min/max of uint16/32/64 (an untyped NotImplementedError; found by review): the range is read
        # in int64, where a uint64 index of 2**63 or more wraps negative
        wide = faces if faces.is_signed() else faces.long()
        lo, hi = (int(x) for x in torch.stack(torch.aminmax(wide)).tolist())  # one device-to-host read
        if lo < 0 and not faces.is_signed():
            raise IndexRangeError(
                f"{name}: expected vertex indices in [0, {num_verts - 1}], found a {faces.dtype} value of 2**63 or more"
            )
        if num_verts == 0:  # "expected vertex indices in [0, -1]" read as a bug of the check (found by review)
            raise IndexRangeError(
                f"{name}: found vertex indices in [{lo}, {hi}], but the vertices are empty (0 vertices to index)"
            )
        if lo < 0 or hi >= num_verts:
            raise IndexRangeError(
                f"{name}: expected vertex indices in [0, {num_verts - 1}], found values in [{lo}, {hi}]"
            )


def check_float_dtype(dtype: object, name: str = "dtype") -> torch.dtype:
    """Require a ``dtype`` argument of torch.float32 or torch.float64, the two vertex dtypes the library computes in.

    A dtype is an argument the data never checked: ``load_mesh(dtype=torch.float16)`` built a half-precision mesh
    that every later check of coordinates refuses, ``torch.int32`` or ``"float32"`` raised torch's own ``TypeError``
    (found by review). A string is refused too, with the dtype to pass.

    Raises:
        DTypeError: naming ``name`` and what was found.

    Example:
        >>> check_float_dtype(torch.float64)
        torch.float64
    """
    if isinstance(dtype, torch.dtype) and dtype in (torch.float32, torch.float64):
        return dtype
    found = f"str {dtype!r}" if isinstance(dtype, str) else repr(dtype)
    hint = f" (pass torch.{dtype})" if dtype in ("float32", "float64") else ""
    raise DTypeError(f"{name}: expected torch.float32 or torch.float64, found {found}{hint}")


def check_lengths(lengths: Tensor, total: int, name: str) -> None:
    """Require a 1-D non-negative integer tensor of per-item sizes that sum to ``total``."""
    check_shape(lengths, ("B",), name)
    if lengths.is_floating_point():
        raise DTypeError(f"{name}: expected an integer tensor, found dtype {lengths.dtype}")
    if lengths.numel() and int(lengths.min()) < 0:
        raise IndexRangeError(f"{name}: expected non-negative lengths, found {lengths.tolist()}")
    if int(lengths.sum()) != total:
        raise ShapeError(f"{name}: expected lengths summing to {total}, found sum {int(lengths.sum())}")


def available_memory() -> int:
    """The memory this process can still take, in bytes: Linux's ``MemAvailable``, else the physical memory.

    ``0`` where the system says neither. Physical memory alone let sizes through that the kernel's OOM killer then
    ended (review X: ``sample --resolution 10000``, at least 9.4 GB, passed on a 23 GB machine with far less free).

    Example:
        >>> available_memory() >= 0
        True
    """
    import os

    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):  # pragma: no cover (not POSIX)
        return 0


def check_allocation(count: float, bytes_each: int, name: str, value: object, what: str) -> None:
    """Refuse, before allocating, a parameter whose result cannot fit: ``count`` elements beyond memory or int64.

    ``count`` is computed by the caller in Python or float64 arithmetic (never a wrapping int64 one) and
    ``bytes_each`` is the working set each element takes (measured by the caller, temporaries included), compared
    with the memory available now (:func:`available_memory`): a refused size would exhaust the machine (an OOM kill,
    which Python cannot report), not merely run slowly.

    Raises:
        SizeLimitError: naming ``name`` and its ``value``, the count and the memory it needs.

    Example:
        >>> check_allocation(1e6, 24, "resolution", 1024, "points")  # 24 MB: fine
        >>> check_allocation(1e19, 24, "num_samples", 10**19, "points")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
            ...
        torchmeshmetric._checks.SizeLimitError: num_samples: 10000000000000000000 asks for about 1e+19 points...
    """
    need = float(count) * bytes_each
    memory = available_memory()
    if not (need <= (memory or float("inf")) and count < 2.0**63):
        where = f"the {memory / 2**30:.3g} GiB of memory available" if memory else "a 64-bit count"
        raise SizeLimitError(
            f"{name}: {value!r} asks for about {float(count):.3g} {what}, about {need / 2**30:.3g} GiB, more than "
            f"{where}; choose a smaller value"
        )


def check_device(device: torch.device | str | int, name: str = "device") -> torch.device:
    """A device this process can use, as a ``torch.device``; else a :class:`DeviceError` naming ``name``.

    Example:
        >>> check_device("cpu")
        device(type='cpu')
        >>> check_device("bogus")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
            ...
        torchmeshmetric._checks.DeviceError: device: 'bogus' is not a device (expected e.g. 'cpu', 'cuda', 'cuda:1'; ...
    """
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError) as exc:
        raise DeviceError(f"{name}: {device!r} is not a device (expected e.g. 'cpu', 'cuda', 'cuda:1'; {exc})") from exc
    if dev.type == "meta":  # tensors there have no values: every check and computation fails (found by review)
        raise DeviceError(f"{name}: {device!r} holds shapes only, no values; use 'cpu' or 'cuda'")
    if dev.type == "cuda":
        if not torch.cuda.is_available():
            raise DeviceError(f"{name}: {device!r} asked, but no CUDA device is available here; use 'cpu'")
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            raise DeviceError(f"{name}: {device!r} asked, but only {torch.cuda.device_count()} CUDA device(s) exist")
    return dev
