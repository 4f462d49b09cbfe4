"""What a non-rigid registration is asked to do: the :class:`Stage` schedule and :class:`NonRigidOptions`.

:class:`NonRigidOptions` holds every setting that decides which registration :func:`register_nonrigid` computes.

:class:`NonRigidOptions` is frozen and validated when built (a ``TypeError`` or ``ValueError`` naming the field), and
its :meth:`~NonRigidOptions.canonical` form (every field, defaults filled, numbers as floats or ints) is what the
evaluation's registration cache hashes: options spelled differently but equal give one key, different ones never
share a key. How the registration runs (device, thread count, closest-face backend, sampling generator, warnings) is
not part of it: see :func:`~torchmeshmetric.registration.register_nonrigid`.
"""

from __future__ import annotations

import inspect
import json
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from functools import cache
from types import MappingProxyType
from typing import Any, NamedTuple

import torch

from torchmeshmetric._checks import check_flag, check_int, check_real
from torchmeshmetric.registration._common import check_sampling
from torchmeshmetric.registration.rigid import check_rigid_options, register_rigid

__all__ = ["DEFAULT_SCHEDULE", "RUN_ARGUMENTS", "NonRigidOptions", "Stage"]

#: Keywords of :func:`~torchmeshmetric.registration.register_nonrigid` that say how it runs, not what it computes.
RUN_ARGUMENTS = frozenset({"device", "generator", "warn", "backend", "num_threads"})


class Stage(NamedTuple):
    """One stage of the coarse-to-fine schedule (distances are fractions of the bounding-box diagonal).

    Attributes:
        regularization: weight (>= 0) of the embedded-deformation prior.
        robust_scale: Geman-McClure scale ``sigma`` (finite, >= :data:`MIN_ROBUST_SCALE`, 1e-12).
        max_distance: correspondences farther than this (finite, > 0) are rejected. Finite: the acceptance weight
            falls smoothly from half this distance to it, so ``inf`` has no meaning (and gave a NaN loss); a
            distance larger than the diagonal (``1.0``) rejects nothing.
        max_normal_angle: correspondences whose normals differ by more (degrees, in ``(0, 180]``) are rejected.
        lr: Adam's initial learning rate (> 0; radians for rotations, diagonals for translations).
        max_steps: Adam steps (>= 0; fewer only at a stationary point).
        lr_decay: the last step's learning rate as a fraction of ``lr`` (in ``(0, 1]``); the rate decays
            geometrically in between, so the stage ends converged instead of at Adam's noise floor of ~``lr``.

    Example:
        >>> first = DEFAULT_SCHEDULE[0]
        >>> first.max_steps, first.max_distance
        (120, 0.3)
        >>> NonRigidOptions(schedule=[first._replace(max_steps=5)]).schedule[0].max_steps  # a shorter stage
        5
    """

    regularization: float
    robust_scale: float
    max_distance: float
    max_normal_angle: float
    lr: float
    max_steps: int
    lr_decay: float = 1e-3


DEFAULT_SCHEDULE: tuple[Stage, ...] = (
    Stage(regularization=10.0, robust_scale=0.10, max_distance=0.30, max_normal_angle=80.0, lr=1e-2, max_steps=120,
          lr_decay=0.5),
    Stage(regularization=1.0, robust_scale=0.05, max_distance=0.15, max_normal_angle=60.0, lr=5e-3, max_steps=50,
          lr_decay=0.5),
    Stage(regularization=0.1, robust_scale=0.02, max_distance=0.08, max_normal_angle=50.0, lr=2e-3, max_steps=50,
          lr_decay=0.5),
    Stage(regularization=0.02, robust_scale=0.01, max_distance=0.05, max_normal_angle=45.0, lr=1e-3, max_steps=80,
          lr_decay=1e-3),
)  # fmt: skip
"""The default coarse-to-fine schedule: regularisation, robust scale, rejection thresholds and step size decrease.

Each stage anneals its step size geometrically (to half its initial rate in the first three, to a thousandth in the
last), so the registration ends converged: under one-ulp and 1e-9-relative input perturbations the registered
vertices of a ~17k-20k-vertex pair move by at most ~1e-12 and ~2e-6 of the diagonal (docs/registration.md,
"Stability"). The last stage runs
80 steps (was 40 at a constant rate) so that it has room to converge."""


MIN_ROBUST_SCALE = 1e-12
"""The smallest ``Stage.robust_scale``: the Geman-McClure kernel ``s^2 r^2 / (s^2 + r^2)`` is 0 / 0 at a residual of 0
once ``s^2`` underflows (``s`` below ~1e-23 in float32, the fused energy's dtype on float32 frames), and far above that
floor every residual the kernels resolve is already in the kernel's flat tail, where it has no gradient."""


def _real(name: str, value: Any, low: float, *, open_low: bool = False, high: float = math.inf) -> float:
    """``value`` as a float in ``[low, high]`` (``(low, high]`` with ``open_low``); NaN never passes."""
    x = check_real(value, name)
    if not ((x > low if open_low else x >= low) and x <= high):
        bounds = f"{'(' if open_low else '['}{low:g}, {high:g}]"
        raise ValueError(f"{name}: expected a float in {bounds}, found {value!r}")
    return x


def _finite(name: str, value: Any, low: float, *, open_low: bool = False) -> float:
    x = _real(name, value, low, open_low=open_low)
    if not math.isfinite(x):
        raise ValueError(f"{name}: expected a finite float, found {value!r}")
    return x


def _stage(name: str, stage: Any) -> Stage:
    """A validated :class:`Stage` with float fields as floats (so ``lr=1`` and ``lr=1.0`` are one stage)."""
    if not isinstance(stage, Stage):
        raise TypeError(f"{name}: expected a Stage, found {type(stage).__name__} {stage!r}")
    return Stage(
        regularization=_finite(f"{name}.regularization", stage.regularization, 0.0),
        robust_scale=_finite(f"{name}.robust_scale", stage.robust_scale, MIN_ROBUST_SCALE),
        max_distance=_finite(f"{name}.max_distance", stage.max_distance, 0.0, open_low=True),
        max_normal_angle=_real(f"{name}.max_normal_angle", stage.max_normal_angle, 0.0, open_low=True, high=180.0),
        lr=_finite(f"{name}.lr", stage.lr, 0.0, open_low=True),
        max_steps=check_int(stage.max_steps, f"{name}.max_steps", 0),
        lr_decay=_real(f"{name}.lr_decay", stage.lr_decay, 0.0, open_low=True, high=1.0),
    )


@cache
def _rigid_defaults() -> Mapping[str, Any]:
    """register_rigid's keyword defaults, less ``generator`` and ``sampling`` (the registration passes its own)."""
    params = inspect.signature(register_rigid).parameters.values()
    passed = ("generator", "sampling")
    defaults = {p.name: p.default for p in params if p.kind is p.KEYWORD_ONLY and p.name not in passed}
    # The registration's rigid stage solves point-to-plane: it converges in fewer iterations on smooth surfaces.
    return MappingProxyType({**defaults, "point_to_plane": True})


def _rigid_options(value: Mapping[str, Any] | None) -> Mapping[str, Any]:
    if value is None:
        return _rigid_defaults()
    if not isinstance(value, Mapping):
        raise TypeError(f"rigid_options: expected a mapping of register_rigid keywords, found {type(value).__name__}")
    defaults = _rigid_defaults()
    unknown = sorted(str(k) for k in value if k not in defaults)
    if unknown:
        raise TypeError(f"rigid_options: expected keywords of register_rigid among {sorted(defaults)}, found {unknown}")
    return MappingProxyType({**defaults, **check_rigid_options(value, "rigid_options: ")})


def _json_value(value: Any) -> Any:
    """A JSON-ready, exact form of a rigid option (tensors by content, like the cache's meshes)."""
    if isinstance(value, torch.Tensor):
        t = value.detach().to("cpu", torch.float64)
        return {"tensor": list(t.shape), "values": t.reshape(-1).tolist()}
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    return repr(value)


@dataclass(frozen=True, eq=False)
class NonRigidOptions:
    """Every setting that decides which registration :func:`register_nonrigid` computes.

    Distances are fractions of the target's bounding-box diagonal. Frozen and validated when built; equal (and
    hashed) by :meth:`canonical`, so options spelled with ints or floats, a list or a tuple of stages, with or without
    the defaults written out, compare equal.

    Args:
        rigid_init: run rigid ICP first.
        node_spacing: deformation-graph node spacing (> 0); raised to ``node_edge_factor * h`` for coarse meshes.
        node_edge_factor: the node spacing is at least this many ``h`` (finite, >= 0; ``h`` the mean edge length of
            the finer of the two meshes, as a fraction of the diagonal; 0 leaves ``node_spacing`` alone). A graph as
            fine as the mesh (below ~1000 vertices 0.03 of the diagonal is about one edge: a node for every two
            vertices) fits the chords of each frame's coarse surface instead of the motion, and converges slowly.
            Measured (docs/registration.md, "Coarse meshes"): at 1.25 the ground-truth RMSE of the demo at
            resolution 24 (420 vertices) falls from 1.17 to 0.98 % of the diagonal and at resolution 16 from 3.3 to
            2.4 %, and of the ground-truth pairs at 314 and 162 vertices by 4-27 % at every motion level; 2 failed on
            the large motion. Meshes with ``h`` below 0.024 (the demo at resolution 48 and above, the paper's
            sizes) keep ``node_spacing``.
        num_neighbors: nodes per vertex (>= 1).
        num_points: source vertices (random subset of the surface vertices) in the data term (>= 1).
        num_target_samples: target surface samples in the reverse term (target → deformed source; >= 0).
        correspondence_every: Adam steps between two correspondence refreshes (>= 1).
        schedule: coarse-to-fine stages, at least one, and at least one with ``max_steps > 0`` (see
            :data:`DEFAULT_SCHEDULE`); kept as a tuple.
        plane_weight: weight (>= 0) of the point-to-plane part of the data terms (forward and reverse).
        point_weight: weight (>= 0) of the point-to-point part of the data terms; one of the two must be > 0.
        reverse_weight: weight (>= 0) of the reverse term.
        adam_eps: Adam's ``eps`` in each stage, as a fraction (>= 0) of the largest gradient component at the stage's
            start (at least torch's 1e-8). Adam normalises each component's step by its own gradient's size, so one
            whose gradient is rounding-level would move by the step size in a direction the input's last bits set;
            with ``eps`` relative, components far below the largest move in proportion to their gradient. 1e-4 keeps
            the ground-truth accuracy (docs/registration.md, "Stability"); 1e-3 cost 4 % of it, 1e-2 cost 25 %.
        tolerance: convergence criterion (>= 0): the fit is reported as not converged when the last stage's loss, on
            the correspondences of its last refresh, still changes between that refresh and its end by more than this
            fraction of its final value (or of the loss of residuals of 1e-5 of the diagonal, when larger: an exact
            fit's loss is rounding). It decides no iterate: every stage runs its steps (or stops at a stationary
            point). Measured (docs/registration.md, "Convergence"): the default schedule ends at 0.7e-4 to 1.0e-4 at
            the paper's sizes and at most 2.5e-4 below 500 vertices, schedules cut after stage 1, 2 or 3 at 1.4e-3 to
            2.6e-2.
        max_outlier_fraction: the fit is reported as failed when more than this fraction (in ``[0, 1]``) of the
            source's surface vertices lies farther than ``max(outlier_distance, outlier_edge_factor * h)`` from the
            target. (Before 2026-12-05 it bounded the target samples too, which ``max_uncovered_fraction`` does now;
            later that day its distance became resolution-aware: ``outlier_distance`` alone called 7 of 40 correct
            fits of the demo at resolution 16 failed.)
        max_uncovered_fraction: the fit is reported as failed when more than this fraction (in ``[0, 1]``) of the
            target samples lies farther than ``max(outlier_distance, outlier_edge_factor * h)`` from the registered
            source: a part of the target left uncovered, the footprint of a limb registered onto another limb, which
            the residual does not see (an area-weighted fraction). Measured (docs/registration.md, "Known failure";
            beyond the default distance, with the per-face target draw): none on 59 correct pairs of 150 to 10k
            vertices; horse-gallop 3 -> 4 1.1 %, 7 -> 9 3.4 %, 5 of 6 CraGL cow pose pairs 0.8-3.8 %.
        outlier_distance: the floor (>= 0) of the distance beyond which a source vertex is an outlier and a target
            sample uncovered.
        outlier_edge_factor: that distance's part relative to the meshes' resolution (finite, >= 0): ``h`` is the
            mean edge length of the finer of the two meshes, as a fraction of the diagonal. A correct fit of coarse
            meshes leaves gaps of a few edges (chords across curved parts, limbs a few edges thick: on the demo at
            resolution 16, edges of 0.053 of the diagonal, up to 9.8 % of the target lay beyond 0.02, 0.85 % beyond 3
            edges, none beyond 4; up to 14 % of the source's vertices beyond 0.02, none beyond 2.4 edges); 0 leaves
            ``outlier_distance`` alone.
        rigid_options: keyword arguments of :func:`register_rigid` (not ``generator``); kept with its defaults
            filled in, ``point_to_plane=True`` unless given.
        sampling: how the data points, the target samples, the graph's nodes and the rigid stage's ICP points are
            chosen. ``"index"`` (default): random draws over the vertex and face indices (the generator's), so the
            same surfaces stored in another order (vertices renumbered, faces shuffled, corners rotated) register
            differently. ``"canonical"``: no random draw; farthest-point subsets of the surface vertices (data and
            ICP points) and of the target's face centroids (target samples, weight 1; every centroid, with area
            weights, when the target has no more faces than ``num_target_samples``), started at the point nearest
            to the exact mean, ties broken by coordinates: the same points for any storage order. ``"dense"``: every
            surface vertex a data point and every target face's centroid a sample (area weights); ``num_points`` and
            ``num_target_samples`` are then ignored (except ``num_target_samples=0``); the ICP points and the nodes
            as with ``"canonical"``. The evaluation's registration uses ``"canonical"`` unless its options name a
            sampling (:data:`~torchmeshmetric.evaluation.pipeline.REGISTRATION_SAMPLING`; docs/registration.md,
            "Stability", "Storage order").

    Raises:
        TypeError: a field of the wrong type (e.g. ``num_points=2.5``), a schedule item that is not a
            :class:`Stage`, or an unknown ``rigid_options`` keyword; the message names the field.
        ValueError: a field out of its range (e.g. ``schedule[1].lr: expected a finite float ...``).

    Example:
        >>> a = NonRigidOptions(num_points=1000, schedule=list(DEFAULT_SCHEDULE[:2]))
        >>> b = NonRigidOptions(num_points=1000, schedule=DEFAULT_SCHEDULE[:2], rigid_options={"point_to_plane": True})
        >>> a == b, hash(a) == hash(b), a == NonRigidOptions()
        (True, True, False)
        >>> NonRigidOptions(correspondence_every=0)
        Traceback (most recent call last):
        ...
        ValueError: correspondence_every: expected an int >= 1, found 0
    """

    rigid_init: bool = True
    node_spacing: float = 0.03
    node_edge_factor: float = 1.25
    num_neighbors: int = 4
    num_points: int = 2000
    num_target_samples: int = 2000
    correspondence_every: int = 10
    schedule: Sequence[Stage] = DEFAULT_SCHEDULE
    plane_weight: float = 1.0
    point_weight: float = 0.1
    reverse_weight: float = 1.0
    adam_eps: float = 1e-6
    tolerance: float = 4e-4
    max_outlier_fraction: float = 0.1
    max_uncovered_fraction: float = 0.005
    outlier_distance: float = 0.02
    outlier_edge_factor: float = 4.0
    rigid_options: Mapping[str, Any] | None = None
    sampling: str = "index"

    def __post_init__(self) -> None:
        if isinstance(self.schedule, (str, bytes)) or not isinstance(self.schedule, Sequence):
            raise TypeError(f"schedule: expected a sequence of Stage, found {type(self.schedule).__name__}")
        if not self.schedule:
            raise ValueError("schedule: expected at least one stage, found none")
        schedule = tuple(_stage(f"schedule[{i}]", s) for i, s in enumerate(self.schedule))
        checked = {
            "rigid_init": check_flag(self.rigid_init, "rigid_init"),
            "node_spacing": _finite("node_spacing", self.node_spacing, 0.0, open_low=True),
            "node_edge_factor": _finite("node_edge_factor", self.node_edge_factor, 0.0),
            "num_neighbors": check_int(self.num_neighbors, "num_neighbors", 1),
            "num_points": check_int(self.num_points, "num_points", 1),
            "num_target_samples": check_int(self.num_target_samples, "num_target_samples", 0),
            "correspondence_every": check_int(self.correspondence_every, "correspondence_every", 1),
            "schedule": schedule,
            "plane_weight": _finite("plane_weight", self.plane_weight, 0.0),
            "point_weight": _finite("point_weight", self.point_weight, 0.0),
            "reverse_weight": _finite("reverse_weight", self.reverse_weight, 0.0),
            "adam_eps": _finite("adam_eps", self.adam_eps, 0.0),
            "tolerance": _finite("tolerance", self.tolerance, 0.0),
            "max_outlier_fraction": _real("max_outlier_fraction", self.max_outlier_fraction, 0.0, high=1.0),
            "max_uncovered_fraction": _real("max_uncovered_fraction", self.max_uncovered_fraction, 0.0, high=1.0),
            "outlier_distance": _real("outlier_distance", self.outlier_distance, 0.0),
            "outlier_edge_factor": _finite("outlier_edge_factor", self.outlier_edge_factor, 0.0),
            "rigid_options": _rigid_options(self.rigid_options),
            "sampling": check_sampling(self.sampling),
        }
        # Settings under which no data can move the graph: the result would be the rigid start, reported converged.
        if not any(stage.max_steps > 0 for stage in schedule):
            raise ValueError(
                "schedule: expected a stage with max_steps > 0, found only stages of 0 steps (no non-rigid fitting "
                "would run; register_rigid is the rigid registration alone)"
            )
        if checked["plane_weight"] == 0 and checked["point_weight"] == 0:
            raise ValueError(
                "plane_weight, point_weight: expected at least one > 0, found both 0 (they weigh the forward and the "
                "reverse data terms alike: no data term would remain)"
            )
        for name, value in checked.items():
            object.__setattr__(self, name, value)

    @classmethod
    def from_keywords(cls, options: NonRigidOptions | None = None, /, **keywords: Any) -> NonRigidOptions:
        """``options`` (default: the defaults) with the fields named in ``keywords`` replaced.

        Raises:
            TypeError: a keyword that is not a field (the message lists the fields), or a bad value (see the class).

        Example:
            >>> NonRigidOptions.from_keywords(NonRigidOptions(num_points=500), tolerance=0.01).num_points
            500
        """
        base = NonRigidOptions() if options is None else options
        if not isinstance(base, NonRigidOptions):
            raise TypeError(f"options: expected NonRigidOptions or None, found {type(base).__name__}")
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(keywords) - set(names))
        if unknown:
            raise TypeError(f"{unknown[0]}: not a registration option; expected one of {names}")
        if not keywords:
            return base
        return cls(**{**{n: getattr(base, n) for n in names}, **keywords})

    @classmethod
    def from_call(cls, keywords: Mapping[str, Any]) -> NonRigidOptions:
        """The options of a call ``register_nonrigid(source, target, **keywords)``.

        ``keywords["options"]`` (if any) updated by the option fields among ``keywords``; the arguments that say how
        the registration runs (``device``, ``generator``, ``warn``, ``backend``, ``num_threads``) are left out, as
        they are not options. This is what a cache keys a registration called with ``keywords`` by.

        Raises:
            TypeError: a keyword that is neither an option nor a run argument, or a bad value.

        Example:
            >>> NonRigidOptions.from_call({"num_points": 500, "num_threads": 2}) == NonRigidOptions(num_points=500)
            True
        """
        given = {k: v for k, v in keywords.items() if k not in RUN_ARGUMENTS}
        return cls.from_keywords(given.pop("options", None), **given)

    def canonical(self) -> dict[str, Any]:
        """JSON-ready form of every field (stages as dicts, defaults filled): the registration cache's key.

        ``sampling`` is left out where it is the default ``"index"``, so that the keys of the registrations cached
        before the option existed stay the same.

        Example:
            >>> first, *_ = NonRigidOptions().canonical()["schedule"]
            >>> first["max_steps"], first["lr"]
            (120, 0.01)
        """
        out: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)}
        out["schedule"] = [s._asdict() for s in self.schedule]
        assert self.rigid_options is not None  # filled by __post_init__
        out["rigid_options"] = {k: _json_value(v) for k, v in sorted(self.rigid_options.items())}
        if out["sampling"] == "index":
            del out["sampling"]  # the default: the keys of the registrations cached before the option stay the same
        return out

    def _key(self) -> str:
        return json.dumps(self.canonical(), sort_keys=True)

    def __reduce__(self) -> tuple[Any, ...]:
        # A read-only mapping view cannot be pickled or deep-copied: rebuild from the plain values instead.
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values["rigid_options"] = dict(values["rigid_options"])
        return (_rebuild, (values,))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, NonRigidOptions):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())


def _rebuild(values: dict[str, Any]) -> NonRigidOptions:
    return NonRigidOptions(**values)
