"""The one cache of registrations of original frame pairs: in memory (optionally bounded) and optionally on disk.

Registering original frame ``k-1`` onto frame ``k`` is by far the most expensive step of the evaluation and of the
temporal loss, and it does not depend on the simplification method, so comparing several methods on one sequence, or
training over many epochs, must not repeat it. The evaluation (:mod:`torchmeshmetric.evaluation`) and the temporal
loss (:class:`~torchmeshmetric.metrics.TemporalLossCache`) both keep their registrations here, under one key
(:func:`registration_key`): a registration computed through one is found by the other when they share a cache.
Entries are keyed by a SHA-256 content hash of both meshes (vertex positions as float64 and faces as int64, with
their shapes), the dtype the registration computes in, and the registration settings; disk entries are written
atomically (temporary file in the same folder, then :func:`os.replace`), so an interrupted run never leaves a
truncated entry behind.

Entries keep the registration's deformation (:class:`~torchmeshmetric.registration.RegistrationWarp`) when it has
one, because the ``flicker`` set moves points other than the registered vertices.

A disk entry holds a SHA-256 checksum of its content (``"sha256"``, over every tensor's bytes and every value), checked
when it is read, and its fields are checked too (shapes, dtypes, finite values, a positive diagonal): ``torch.load``
does not check a zip's CRCs, and a zeroed block of an entry loaded silently with other figures (37 of 55 blocks of a
28 kB entry), a NaN in the deformation crashed every rerun. An entry that fails either check is damaged: a warning
names its file and why, and it is recomputed and replaced, never trusted.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
import os
import re
import sys
import time
import uuid
import warnings
import weakref
from collections import OrderedDict
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import torch
from torch import Tensor

from torchmeshmetric._atomic import atomic_write_with
from torchmeshmetric._checks import ShapeError, check_flag, check_int
from torchmeshmetric._checksum import content_sha256
from torchmeshmetric.registration._common import registration_dtype
from torchmeshmetric.registration.nonrigid import register_nonrigid
from torchmeshmetric.registration.options import NonRigidOptions
from torchmeshmetric.registration.warp import RegistrationWarp, Warp
from torchmeshmetric.structures import Mesh

__all__ = [
    "DEFAULT_REGISTER",
    "REGISTRATION_RESULTS_VERSION",
    "CachedRegistration",
    "RegistrationCache",
    "compute_registration",
    "default_registration_settings",
    "object_name",
    "registration_fn_name",
    "registration_key",
]

_FORMAT = "torchmeshmetric-registration-cache-v1"

#: The revision of the library's registration results, part of the cache key of every registration it computes
#: (:func:`default_registration_settings`; the evaluation's and the temporal loss's). Raise it in every change that
#: changes a registration's result without adding an option (the algorithm, its draws, a kernel it calls, a
#: default): entries of the earlier revisions then miss and are recomputed, never served (docs/architecture.md,
#: "Where to add ..."). 1: the first revision in the key (review I, 2026-12); before it, fixes that changed every
#: registration (e.g. target samples drawn by face index) kept their keys.
#: 2: the settings name the dtype the registration computes in (``"computes_in"``), and the evaluation's registration
#: computes in float64 whatever the frames' dtype (review L, 2026-12).
#: 3: the evaluation's registration samples with ``sampling="canonical"`` unless its options name one (the key's
#: options then name ``"sampling"``; review L #1, 2026-12).
REGISTRATION_RESULTS_VERSION = 3

#: The ``"register"`` name in the settings of the library's registration: the qualified name of the evaluation's
#: ``default_register``, under which disk caches have stored its entries since the first format. Kept verbatim (a
#: test checks it still names that function).
DEFAULT_REGISTER = "torchmeshmetric.evaluation.pipeline.default_register"


class CachedRegistration(NamedTuple):
    """What the cache keeps of a registration of frame ``k-1`` onto frame ``k`` (for the evaluation and the loss).

    Attributes:
        verts: ``(V_{k-1}, 3)`` registered vertices (topology of frame ``k-1``), on the CPU.
        residual: ``(V_{k-1},)`` distance of each registered vertex to the surface of frame ``k``, on the CPU.
        converged: the registration's convergence flag.
        seconds: wall time the registration took when it was computed.
        warp: the registration's deformation as a map of arbitrary points of frame ``k-1`` to frame ``k``, in the
            dtype the registration computed in (the evaluation's: float64, whatever the frames' dtype)
            (:data:`~torchmeshmetric.registration.Warp`), or ``None`` when only the registered vertices are known
            (then the evaluation interpolates them: :class:`~torchmeshmetric.registration.SurfaceWarp`). The cache
            keeps a :class:`~torchmeshmetric.registration.RegistrationWarp` and drops any other callable (it cannot
            be stored), so an entry is the same from memory and from disk.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.registration import DEFAULT_SCHEDULE
        >>> from torchmeshmetric.structures import as_mesh
        >>> m = as_mesh(trimesh.creation.icosphere(subdivisions=1))
        >>> reg = compute_registration(m, m, schedule=[DEFAULT_SCHEDULE[0]._replace(max_steps=5)])
        >>> tuple(reg.verts.shape), tuple(reg.residual.shape), reg.converged, reg.registered_mesh(m).num_faces
        ((42, 3), (42,), True, 80)
    """

    verts: Tensor
    residual: Tensor
    converged: bool
    seconds: float
    warp: Warp | None = None

    def registered_mesh(self, source: Mesh) -> Mesh:
        """Frame ``k-1`` registered onto frame ``k``: the registered vertices on ``source``'s faces.

        Args:
            source: original frame ``k-1`` (the registration's source); the mesh gets its device and dtype.

        Raises:
            ShapeError: when the registered vertices are not ``(V, 3)`` with ``V`` the vertices of ``source``.

        Example:
            >>> import torch
            >>> m = Mesh(torch.eye(3), torch.tensor([[0, 1, 2]]))
            >>> reg = CachedRegistration(m.verts + 1, torch.zeros(3), True, 0.0)
            >>> reg.registered_mesh(m).verts[0].tolist()
            [2.0, 1.0, 1.0]
        """
        if tuple(self.verts.shape) != tuple(source.verts.shape):
            raise ShapeError(
                f"source: expected vertices of shape {tuple(self.verts.shape)} (those registered), found "
                f"{tuple(source.verts.shape)}"
            )
        return Mesh(self.verts.to(source.verts), source.faces, validate=False)


def _hash_mesh(h: hashlib._Hash, mesh: Mesh) -> None:
    v = mesh.verts.detach().to("cpu", torch.float64).contiguous()
    f = mesh.faces.detach().to("cpu", torch.int64).contiguous()
    h.update(repr((tuple(v.shape), tuple(f.shape))).encode())
    h.update(v.numpy().tobytes())
    h.update(f.numpy().tobytes())


# Tags a NonRigidOptions in the hashed JSON, so that no plain mapping of settings can spell the same text.
_OPTIONS_TAG = "__torchmeshmetric.NonRigidOptions__"


def _settings_json(value: object) -> object:
    """``json.dumps`` fallback: :class:`NonRigidOptions` by their canonical form, anything else by ``str``."""
    if isinstance(value, NonRigidOptions):
        return {_OPTIONS_TAG: value.canonical()}
    return str(value)


_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")  # the default repr of an object, a function or a method


def _settings_text(settings: Mapping[str, object] | NonRigidOptions) -> tuple[str, str | None]:
    """The settings' JSON text (their part of the key) and the ``str`` of the first one keyed by a memory address.

    A setting that JSON cannot write counts by its ``str``; the default one (``<Loss object at 0x7f...>``, a
    function) holds the object's address, which no other process shares, so such a key is found in this process
    only: an on-disk cache keyed so missed in every new process, without a word (found by the docstrings' review).
    """
    if isinstance(settings, NonRigidOptions):
        return json.dumps(_settings_json(settings), sort_keys=True), None
    fleeting: list[str] = []

    def fallback(value: object) -> object:
        text = _settings_json(value)
        if isinstance(text, str) and _ADDRESS.search(text):
            fleeting.append(text)
        return text

    text = json.dumps(dict(settings), sort_keys=True, default=fallback)
    return text, (fleeting[0] if fleeting else None)


def registration_key(source: Mesh, target: Mesh, settings: Mapping[str, object] | NonRigidOptions) -> str:
    """SHA-256 hex digest identifying the registration of ``source`` onto ``target`` with ``settings``.

    The meshes count by content: vertices as float64 and faces as int64 with their shapes, so a frame's storage does
    not matter, and the dtype the registration computes in (the meshes' promoted, at least float32) counts: a float32
    registration and a float64 one of the same vertex values differ by 5-45 % of the registration's own error (the
    optimisation amplifies float32's rounding; measured on the demo at resolutions 32 to 128), so a float64 run must
    not be served float32 registrations. The device and the thread count are left out: the CPU's thread counts agree
    bit for bit, and a cache serves one registration per problem across devices. A
    :class:`~torchmeshmetric.registration.NonRigidOptions`, given as ``settings`` or as a value inside them, counts
    by its :meth:`~torchmeshmetric.registration.NonRigidOptions.canonical` form: every field, defaults filled, so
    equal options spelled differently give one key and different options never share one.

    Args:
        source: original frame ``k-1``.
        target: original frame ``k``.
        settings: registration settings (anything that changes the result): JSON-serialisable values or
            :class:`~torchmeshmetric.registration.NonRigidOptions`, or the options themselves.

    Returns:
        The key: 64 lowercase hexadecimal characters. A setting JSON cannot write (nor a ``NonRigidOptions``)
        counts by its ``str``; where that ``str`` holds a memory address (an object without its own ``__str__``, a
        function), the key lasts only as long as this process, and :meth:`RegistrationCache.get_or_compute` keeps
        such entries in memory, with a warning, never in its folder.

    Example:
        >>> import torch
        >>> from torchmeshmetric.registration import DEFAULT_SCHEDULE, NonRigidOptions
        >>> m = Mesh(torch.eye(3), torch.tensor([[0, 1, 2]]))
        >>> registration_key(m, m, {"a": 1}) == registration_key(m, m, {"a": 1})
        True
        >>> registration_key(m, m, {"a": 1}) == registration_key(m, m, {"a": 2})
        False
        >>> quick = NonRigidOptions(schedule=DEFAULT_SCHEDULE[:2])
        >>> registration_key(m, m, quick) == registration_key(m, m, NonRigidOptions(schedule=list(quick.schedule)))
        True
    """
    h = hashlib.sha256(_FORMAT.encode())
    _hash_mesh(h, source)
    _hash_mesh(h, target)
    h.update(str(registration_dtype(source, target)).encode())
    # plain settings by their JSON text (a NonRigidOptions, alone or inside, by its canonical form)
    h.update(_settings_text(settings)[0].encode())
    return h.hexdigest()


def registration_fn_name(register: object) -> str | None:
    """The name that identifies a caller's registration function in every process, or ``None`` when none does.

    The cache stores a function's registrations on disk under this name, so it must stand for what the function
    computes, across runs and machines:

    * a ``cache_key`` attribute, a non-empty str, on any callable (a ``functools.partial``, a lambda, an object):
      ``"cache_key:<it>"``; the caller names the function and its settings, and changes the name when the results
      change;
    * a plain function found under its qualified name in its module (defined at the top level, or in a class body):
      ``"<module>.<qualname>"``; a script's function (module ``__main__``) by the script's resolved path:
      ``"<path>:<qualname>"``, so that two scripts' ``register`` are two functions;
    * anything else has no such name (a lambda, a closure, a ``functools.partial``, a bound method, a callable
      object): every ``functools.partial`` was ``"functools.partial"`` and every lambda of a module
      ``"<module>.<lambda>"``, so two of them shared entries. The cache keys those by the object itself, in memory
      (:meth:`RegistrationCache.session_name`).

    A function edited between runs keeps its name: give it a ``cache_key`` that changes with it (or another cache
    folder) when its results change.

    Raises:
        TypeError: a ``cache_key`` that is not a non-empty str.

    Example:
        >>> import functools
        >>> registration_fn_name(registration_key), registration_fn_name(functools.partial(registration_key))
        ('torchmeshmetric.registration.cache.registration_key', None)
        >>> named = functools.partial(registration_key)
        >>> named.cache_key = "my-registration-v2"
        >>> registration_fn_name(named), registration_fn_name(lambda s, t: s)
        ('cache_key:my-registration-v2', None)
    """
    key = getattr(register, "cache_key", None)
    if key is not None:
        if not isinstance(key, str) or not key:
            raise TypeError(
                f"registration_fn.cache_key: expected a non-empty str naming what the function computes, found "
                f"{type(key).__name__} {key!r}"
            )
        return f"cache_key:{key}"
    if not inspect.isfunction(register):
        return None
    module_name, qualname = register.__module__, register.__qualname__
    found: object = sys.modules.get(module_name)
    for part in qualname.split("."):  # "<lambda>" and "f.<locals>.g" are found nowhere
        found = getattr(found, part, None)
    if found is not register:  # not the function its module holds under that name (a copy made by a factory)
        return None
    if module_name == "__main__":
        script = getattr(sys.modules["__main__"], "__file__", None)
        return None if script is None else f"{Path(script).resolve()}:{qualname}"
    return f"{module_name}.{qualname}"


def default_registration_settings(options: NonRigidOptions, computes_in: torch.dtype) -> dict[str, object]:
    """The settings that key the library's registration (:func:`compute_registration` with ``options``).

    What the evaluation (``registration_fn=None``) and the temporal loss both pass to :func:`registration_key`, so
    that they find each other's entries: the function's name, :data:`REGISTRATION_RESULTS_VERSION`, the options and
    the dtype the registration computes in. The evaluation's computes in float64 whatever the frames' dtype
    (:data:`~torchmeshmetric.evaluation.pipeline.REGISTRATION_DTYPE`), the temporal loss's in the frames' dtype, so
    they share entries of float64 frames (given the same options: the evaluation samples with ``"canonical"`` unless
    told otherwise, the loss with ``"index"``) and keep float32 frames' two registrations apart (the key's frame
    dtype, the entry's dtype, does not tell them apart). The backend, device and thread count are left out: the exact
    backends and the CPU's thread counts give the same registration bit for bit.

    Args:
        options: the registration's complete options.
        computes_in: the dtype the registration computes in (the ``dtype`` of :func:`compute_registration`, or the
            frames' promoted dtype, at least float32, when it has none).

    Returns:
        ``{"register": DEFAULT_REGISTER, "results_version": REGISTRATION_RESULTS_VERSION, "options": options,
        "computes_in": "float32" | "float64"}``.

    Example:
        >>> settings = default_registration_settings(NonRigidOptions(), torch.float64)
        >>> settings["register"] == DEFAULT_REGISTER, settings["results_version"] == REGISTRATION_RESULTS_VERSION
        (True, True)
        >>> settings["computes_in"]
        'float64'
    """
    return {
        "register": DEFAULT_REGISTER,
        "results_version": REGISTRATION_RESULTS_VERSION,
        "options": options,
        "computes_in": str(computes_in).removeprefix("torch."),
    }


def compute_registration(
    source: Mesh,
    target: Mesh,
    *,
    device: torch.device | str | None = None,
    dtype: torch.dtype | None = None,
    **options: Any,
) -> CachedRegistration:
    """Register ``source`` (frame ``k-1``) onto ``target`` (frame ``k``) as a cache entry, timed.

    Calls :func:`~torchmeshmetric.registration.register_nonrigid` (rigid initialisation, then the deformation graph)
    with ``options`` (its keywords: ``options=NonRigidOptions(...)``, fields, ``backend``) and keeps the registered
    vertices ``(V_{k-1}, 3)``, the residual ``(V_{k-1},)``, the convergence flag, the wall time and the deformation
    (:class:`~torchmeshmetric.registration.RegistrationWarp`, which moves any point: the ``flicker`` set and the
    temporal loss need it).

    Args:
        source: original frame ``k-1``.
        target: original frame ``k``.
        device: where the registration runs (default: where the frames are).
        dtype: the dtype the registration computes in; the frames are cast to it (float32 to float64 is exact),
            the registered vertices and the residual are cast back to the frames' promoted dtype (at least float32)
            and the deformation is kept in ``dtype``: a float64 warp moves float32 points in float64 and rounds
            them once (:class:`~torchmeshmetric.registration.RegistrationWarp`), so the ``flicker`` set and the
            registered temporal forms are as portable as the registered vertices.
            ``None``: the frames' promoted dtype, as :func:`~torchmeshmetric.registration.register_nonrigid`.
            float32's Adam steps and stopping rule amplify the CPU kernels' rounding (``at::sqrt``/``sin``/``cos``,
            the fused Adam's vector math), so a float32 registration is another computation on another CPU; the
            evaluation computes in float64 (docs/statistics.md, "The same figures on every machine").
        **options: keywords of :func:`~torchmeshmetric.registration.register_nonrigid`.

    Returns:
        :class:`CachedRegistration`: ``verts`` ``(V_{k-1}, 3)`` and ``residual`` ``(V_{k-1},)`` in the frames'
        promoted dtype, on the CPU; ``converged``; ``seconds`` (wall time); ``warp`` (a
        :class:`~torchmeshmetric.registration.RegistrationWarp` in ``dtype``).

    Raises:
        TypeError: an option :func:`~torchmeshmetric.registration.register_nonrigid` does not take; and its errors
            on bad frames.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.registration import DEFAULT_SCHEDULE
        >>> from torchmeshmetric.structures import as_mesh
        >>> m = as_mesh(trimesh.creation.icosphere(subdivisions=1))
        >>> quick = [DEFAULT_SCHEDULE[0]._replace(max_steps=5)]
        >>> reg = compute_registration(m, m, schedule=quick)
        >>> tuple(reg.verts.shape) == tuple(m.verts.shape), type(reg.warp).__name__
        (True, 'RegistrationWarp')
        >>> m32 = m.to(dtype=torch.float32)
        >>> reg = compute_registration(m32, m32, dtype=torch.float64, schedule=quick)
        >>> reg.verts.dtype, reg.residual.dtype, reg.warp.nodes.dtype
        (torch.float32, torch.float32, torch.float64)
    """
    frames_dtype = registration_dtype(source, target)
    start = time.perf_counter()
    if dtype is None or dtype == frames_dtype:
        result = register_nonrigid(source, target, device=device, **options)
        warp = RegistrationWarp.from_registration(result, target)
    else:
        wide_target = target.to(dtype=dtype)
        result = register_nonrigid(source.to(dtype=dtype), wide_target, device=device, **options)
        warp = RegistrationWarp.from_registration(result, wide_target)
    seconds = time.perf_counter() - start
    verts, residual = result.verts.detach().to(frames_dtype), result.residual.detach().to(frames_dtype)
    return CachedRegistration(verts, residual, bool(result.converged), seconds, warp)


def _entry_problem(entry: CachedRegistration, num_verts: int) -> str | None:
    """What is wrong with an entry read from disk for a source of ``num_verts`` vertices, or ``None``."""
    verts, residual = entry.verts, entry.residual
    if not isinstance(verts, Tensor) or not verts.is_floating_point() or tuple(verts.shape) != (num_verts, 3):
        found = tuple(verts.shape) if isinstance(verts, Tensor) else type(verts).__name__
        return f"invalid: verts expected a float tensor of shape ({num_verts}, 3), found {found}"
    if not isinstance(residual, Tensor) or not residual.is_floating_point() or tuple(residual.shape) != (num_verts,):
        found = tuple(residual.shape) if isinstance(residual, Tensor) else type(residual).__name__
        return f"invalid: residual expected a float tensor of shape ({num_verts},), found {found}"
    for name, t in (("verts", verts), ("residual", residual)):
        bad = int((~torch.isfinite(t)).sum())
        if bad:
            return f"invalid: {name} holds {bad} NaN/Inf value(s)"
    if bool((residual < 0).any()):
        return "invalid: residual holds negative distances"
    if not isinstance(entry.converged, bool):
        return f"invalid: converged expected a bool, found {type(entry.converged).__name__} {entry.converged!r}"
    if isinstance(entry.seconds, bool) or not isinstance(entry.seconds, (int, float)) or not entry.seconds >= 0:
        return f"invalid: seconds expected a number >= 0, found {entry.seconds!r}"
    return None


def _read_entry(data: object, num_verts: int) -> tuple[CachedRegistration | None, str | None]:
    """``(entry, None)`` from what ``torch.load`` read, or ``(None, why it is damaged)``."""
    if not isinstance(data, dict):
        return None, f"invalid: expected a dict of the entry's fields, found {type(data).__name__}"
    stored = data.pop("sha256", None)
    if stored is None:
        return None, "invalid: it holds no checksum (sha256)"
    if stored != content_sha256(data):
        return None, "damaged: its content does not match its checksum (sha256)"
    fields = ("verts", "residual", "converged", "seconds", "warp")
    if set(data) != set(fields):
        return None, f"invalid: expected the fields {list(fields)}, found {sorted(data)}"
    try:
        warp = None if data["warp"] is None else RegistrationWarp.from_state(data["warp"])
    except (TypeError, ValueError) as exc:  # the typed errors of the warp's checks, each naming its field
        return None, f"invalid: {exc}"
    entry = CachedRegistration(data["verts"], data["residual"], data["converged"], data["seconds"], warp)
    problem = _entry_problem(entry, num_verts)
    return (None, problem) if problem is not None else (entry._replace(seconds=float(entry.seconds)), None)


def _described(register: object) -> str:
    """A registration function in messages: its module and qualified name, what a partial wraps, or its type."""
    if isinstance(register, functools.partial):
        return f"functools.partial({_described(register.func)}, ...)"
    name = getattr(register, "__qualname__", None)
    if isinstance(name, str):
        return f"{getattr(register, '__module__', '?')}.{name}"
    kind = type(register)
    return f"a {kind.__module__}.{kind.__qualname__} object"


def object_name(register: object) -> str:
    """A registration function without a lasting name (:func:`registration_fn_name`), named by the object itself.

    Unique among the objects alive at once: a metric that names its function this way holds it, so two metrics
    compared by their settings name one function alike and two functions apart (every lambda and partial had the
    default registration's ``None``, so ``TemporalConsistency`` merged their sets and grouped them; found by review J).

    Example:
        >>> f = lambda s, t: s
        >>> object_name(f) == object_name(f) != object_name(lambda s, t: s)
        True
    """
    return f"object {_described(register)} at {id(register):#x}"


def _forget_session(sessions: dict[int, tuple[Callable[[], object], str]], key: int, ref: object) -> None:
    """Drop a dead function's session name (the weak reference's callback; a later object may hold its id now)."""
    entry = sessions.get(key)
    if entry is not None and entry[0] is ref:
        del sessions[key]


def _same(value: object) -> object:
    """``value``: a strong reference called as a weak one is."""
    return value


def _copied(entry: CachedRegistration) -> CachedRegistration:
    """``entry`` with tensors of its own (the cache's entries never share memory with what callers hold)."""
    warp = entry.warp.clone() if isinstance(entry.warp, RegistrationWarp) else entry.warp
    return entry._replace(verts=entry.verts.clone(), residual=entry.residual.clone(), warp=warp)


def _storable(warp: Warp | None) -> dict[str, Any] | None:
    return warp.state() if isinstance(warp, RegistrationWarp) else None


class RegistrationCache:
    """Registrations keyed by content (:func:`registration_key`), in memory and, given a ``directory``, on disk.

    Args:
        directory: folder for ``<key>.pt`` entries (created when needed); ``None`` keeps entries in memory only.
        max_entries: entries kept in memory; beyond it the least recently used is dropped from memory (never from
            disk, where a later lookup finds it again). ``None``: unbounded.

    A folder that cannot be written (read-only, full) is read all the same; the first entry that cannot be stored
    gives one warning naming the folder, and the cache then keeps its new entries in memory only: a read-only archive
    of precomputed registrations serves what it holds, and the rest is computed.

    Raises:
        TypeError: ``max_entries`` not an int or ``None`` (numpy's and one-element integer tensors are ints).
        ValueError: ``max_entries`` below 1, or ``directory`` an existing file (checked here: an entry is stored only
            after its registration ran, too late to learn it cannot be).

    Attributes:
        hits: number of lookups answered from memory or disk.
        misses: number of lookups that ran the registration.
        unwritable: why the folder could not be written, or ``None``.

    Example:
        >>> import torch
        >>> cache = RegistrationCache()
        >>> m = Mesh(torch.eye(3), torch.tensor([[0, 1, 2]]))
        >>> make = lambda: CachedRegistration(m.verts, torch.zeros(3), True, 0.0)
        >>> _ = cache.get_or_compute(m, m, {}, make); _ = cache.get_or_compute(m, m, {}, make)
        >>> cache.hits, cache.misses
        (1, 1)
    """

    def __init__(self, directory: str | os.PathLike[str] | None = None, *, max_entries: int | None = None) -> None:
        if max_entries is not None:
            max_entries = check_int(max_entries, "max_entries", 1)
        self.directory = None if directory is None else Path(directory)
        if self.directory is not None and self.directory.exists() and not self.directory.is_dir():
            raise ValueError(f"directory: expected a folder for the cache's entries, found the file {str(directory)!r}")
        self.max_entries = max_entries
        # Set at the first failed store (after one warning): the cache then stores nothing more, and reads the folder.
        self.unwritable: str | None = None
        self._memory: OrderedDict[str, CachedRegistration] = OrderedDict()
        self.hits = 0
        self.misses = 0
        #: When a dict: every entry :meth:`get_or_compute` returns is also recorded there by key (the ranks of a
        #: distributed evaluation send each other the entries they computed or loaded).
        self.journal: dict[str, CachedRegistration] | None = None
        # Functions without a lasting name, by id: (a reference to the function, its name). A weak reference where
        # the object takes one: a strong one kept every lambda and partial alive with whatever they hold (a model
        # captured in a partial outlived its last user; found by review J). The entry goes with its function, so an
        # id reused by a later object never finds the name (the reference is checked too).
        self._sessions: dict[int, tuple[Callable[[], object], str]] = {}
        self._warned: set[str] = set()  # settings keyed by a memory address already warned about

    def session_name(self, register: object) -> str:
        """The name of a registration function without a lasting one (:func:`registration_fn_name`) in this cache.

        Unique to the function object (a random token: no other object, process or rank gets it), so its entries are
        found again for this object only; :meth:`get_or_compute` keeps them in memory (``on_disk=False``). With a
        folder, the first call for a function warns that its registrations are not stored there.
        """
        found = self._sessions.get(id(register))
        if found is not None and found[0]() is register:
            return found[1]
        described = _described(register)
        name = f"session:{described}:{uuid.uuid4().hex}"
        ref: Callable[[], object]
        try:
            ref = weakref.ref(register, functools.partial(_forget_session, self._sessions, id(register)))
        except TypeError:  # an object that takes no weak reference (__slots__ without it): held, as it must be
            ref = functools.partial(_same, register)
        self._sessions[id(register)] = (ref, name)
        if self.directory is not None:
            warnings.warn(
                f"registration cache: registration_fn {described} has no name that lasts beyond this process (a plain "
                "function defined at a module's top level has one; give any other callable a cache_key attribute, a "
                f"str naming what it computes); its registrations are kept in memory only, not in {self.directory}",
                UserWarning,
                stacklevel=4,
            )
        return name

    def __getstate__(self) -> dict[str, object]:
        # A copy (deepcopy, pickle) names no function of this cache's: its objects may not be there (a lambda does not
        # pickle), and an id could name another object there.
        return {**self.__dict__, "_sessions": {}}

    def adopt(self, entries: Mapping[str, CachedRegistration]) -> None:
        """Answer later lookups of these entries (by key, e.g. another rank's :attr:`journal`) from memory."""
        for key, entry in entries.items():
            self._remember(key, _copied(entry))  # this rank's own journal holds what its callers were handed

    def _remember(self, key: str, entry: CachedRegistration) -> None:
        """Keep ``entry`` in memory as the most recently used, dropping the least recently used beyond the bound."""
        self._memory[key] = entry
        self._memory.move_to_end(key)
        if self.max_entries is not None:
            while len(self._memory) > self.max_entries:
                self._memory.popitem(last=False)

    def _path(self, key: str) -> Path:
        assert self.directory is not None
        return self.directory / f"{key}.pt"

    def _load(self, key: str, source: Mesh) -> CachedRegistration | None:
        if self.directory is None or not self._path(key).is_file():
            return None
        entry: CachedRegistration | None = None
        problem: str | None
        try:
            data = torch.load(self._path(key), map_location="cpu", weights_only=True)
        except Exception as exc:  # a corrupt entry is recomputed and replaced, never trusted
            problem = f"unreadable ({type(exc).__name__}: {exc})"
        else:
            entry, problem = _read_entry(data, source.num_verts)
        if entry is None:
            warnings.warn(f"registration cache: entry {self._path(key)} is {problem}; recomputing it", stacklevel=4)
            return None
        return entry

    def _store(self, key: str, entry: CachedRegistration) -> None:
        if self.directory is None or self.unwritable is not None:
            return
        # Unique temporary name, fsync, then rename: ranks and concurrent runs sharing the folder may store the same
        # key at once; a reader sees a complete entry (one of theirs) or none, never a mix or a truncated file.
        payload: dict[str, object] = {**entry._asdict(), "warp": _storable(entry.warp)}
        payload["sha256"] = content_sha256(payload)
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            # Written at once even inside a report's atomic_file_set: a registration is worth keeping on any outcome.
            atomic_write_with(self._path(key), lambda fh: torch.save(payload, fh), overwrite=True, join_file_set=False)
        except OSError as exc:
            # A folder that cannot be written (read-only: an archive of precomputed registrations; full) failed the
            # whole campaign at its first miss, after the work, naming a temporary file. The registration is worth
            # more than its copy on disk: the run goes on, keeping it in memory, and reads the folder still.
            self.unwritable = exc.strerror or str(exc)
            warnings.warn(
                f"registration cache: cannot store entries in {self.directory} ({self.unwritable}); this run keeps "
                "its registrations in memory only (the entries already there are still read)",
                UserWarning,
                stacklevel=4,
            )

    def get_or_compute(
        self,
        source: Mesh,
        target: Mesh,
        settings: Mapping[str, object],
        compute: Callable[[], CachedRegistration],
        *,
        on_disk: bool = True,
    ) -> tuple[CachedRegistration, bool]:
        """Return the cached registration of ``source`` onto ``target``, computing and storing it on a miss.

        Args:
            source: original frame ``k-1``.
            target: original frame ``k``.
            settings: registration settings that are part of the key.
            compute: called on a miss; its result is stored (detached, on the CPU).
            on_disk: read and write the folder (when the cache has one); ``False`` for settings that name nothing
                beyond this process (:meth:`session_name`). Settings with a value keyed by a memory address
                (:func:`registration_key`) are kept in memory whatever this says, with a warning.

        Returns:
            ``(entry, hit)``; the entry's tensors are the caller's own (copies of the cache's), so editing them in
            place changes no later lookup.
        """
        on_disk = check_flag(on_disk, "on_disk")
        fleeting = _settings_text(settings)[1]
        if on_disk and fleeting is not None:
            on_disk = False  # its key is found in this process only: a stored entry would never be read again
            warned = self.__dict__.setdefault("_warned", set())  # (a cache pickled before it had the set)
            if self.directory is not None and fleeting not in warned:
                warned.add(fleeting)
                warnings.warn(
                    f"registration cache: a registration setting, {fleeting}, is keyed by its str, which holds a "
                    "memory address that no later process shares; its registrations are kept in memory only, not in "
                    f"{self.directory} (give the setting as a JSON value: a name, a number, a list)",
                    UserWarning,
                    stacklevel=2,
                )
        key = registration_key(source, target, settings)
        entry, hit = self._lookup_or_compute(key, source, compute, on_disk)
        if self.journal is not None:
            self.journal[key] = entry
        return entry, hit

    def _lookup_or_compute(
        self, key: str, source: Mesh, compute: Callable[[], CachedRegistration], on_disk: bool
    ) -> tuple[CachedRegistration, bool]:
        # The cache keeps its own tensors and hands out copies: a caller that edits a registration in place (scaling
        # its registered mesh) changed every later hit of this process, not the disk entry, so one command gave other
        # figures in a fresh process.
        entry = self._memory.get(key)
        if entry is None and on_disk:
            entry = self._load(key, source)
        if entry is not None:
            self._remember(key, entry)
            self.hits += 1
            return _copied(entry), True
        self.misses += 1
        fresh = compute()
        warp = fresh.warp.to("cpu") if isinstance(fresh.warp, RegistrationWarp) else None
        given = CachedRegistration(
            fresh.verts.detach().cpu(), fresh.residual.detach().cpu(), bool(fresh.converged), float(fresh.seconds), warp
        )
        entry = _copied(given)
        self._remember(key, entry)
        if on_disk:
            self._store(key, entry)
        return given, False

    def __len__(self) -> int:
        """Entries held in memory."""
        return len(self._memory)
