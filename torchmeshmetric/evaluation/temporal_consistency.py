"""``TemporalConsistency``: the paper's evaluation as a ``torchmetrics.Metric`` for validation loops."""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor

from torchmeshmetric._checks import check_flag
from torchmeshmetric.evaluation.flicker import FLICKER
from torchmeshmetric.evaluation.pipeline import (
    REGISTRATION_SAMPLING,
    RegisterFn,
    RegistrationOptions,
    evaluate_pair,
    registration_keywords,
    registration_settings,
)
from torchmeshmetric.evaluation.results import SET_NAMES, flatten_statistics
from torchmeshmetric.kernels import IndexCache
from torchmeshmetric.kernels.select import check_backend
from torchmeshmetric.metrics._plot import StatisticsPlot
from torchmeshmetric.metrics.distance_states import DistanceStates, DistanceStatesMetric
from torchmeshmetric.registration.cache import RegistrationCache, object_name
from torchmeshmetric.registration.options import NonRigidOptions
from torchmeshmetric.structures import MeshLike

__all__ = ["TemporalConsistency"]

# The states of each set (paper Fig. 2, plus flicker), per direction, written out so that each can be found by name;
# each is a distance set accumulated like the metrics' (see DistanceStates). Adding a set to SET_NAMES needs a row here.
_FORWARD_STATES: dict[str, DistanceStates] = {
    "surface_k_minus_1": DistanceStates("surface_k_minus_1_moments", "surface_k_minus_1_values"),
    "surface_k": DistanceStates("surface_k_moments", "surface_k_values"),
    "vertex_k_minus_1": DistanceStates("vertex_k_minus_1_moments", "vertex_k_minus_1_values"),
    "vertex_k": DistanceStates("vertex_k_moments", "vertex_k_values"),
    FLICKER: DistanceStates("flicker_moments", "flicker_values"),
}
_REVERSE_STATES: dict[str, DistanceStates] = {
    "surface_k_minus_1": DistanceStates("reverse_surface_k_minus_1_moments", "reverse_surface_k_minus_1_values"),
    "surface_k": DistanceStates("reverse_surface_k_moments", "reverse_surface_k_values"),
    "vertex_k_minus_1": DistanceStates("reverse_vertex_k_minus_1_moments", "reverse_vertex_k_minus_1_values"),
    "vertex_k": DistanceStates("reverse_vertex_k_moments", "reverse_vertex_k_values"),
    FLICKER: DistanceStates("reverse_flicker_moments", "reverse_flicker_values"),
}


class TemporalConsistency(StatisticsPlot, DistanceStatesMetric):
    """Temporal consistency of simplified frames (paper Fig. 2) accumulated over validation steps.

    Each :meth:`update` evaluates one simplified frame ``k`` against original frames ``k`` and ``k-1`` with
    :func:`~torchmeshmetric.evaluation.evaluate_pair` (registration of ``k-1`` onto ``k`` cached in memory per
    original pair, keyed by content, so validating every epoch on the same frames registers each pair once) and
    accumulates the four distance sets, each in the states of one distance set as the metrics of
    :mod:`torchmeshmetric.metrics` keep them (merged moments and the values, see
    :class:`~torchmeshmetric.metrics.distance_states.DistanceStates`). :meth:`compute` pools all updates (and all
    processes under DDP) and returns ``{set_name: {statistic: tensor}}`` for the four sets, plus ``"reverse"``
    when two-sided. Pooling differs from the sequence report's aggregate, which averages per-pair statistics as the
    paper's Tables III/IV do. Use :func:`~torchmeshmetric.evaluation.flatten_statistics` for ``log_dict``.

    With ``flicker=True`` the metric also accumulates the ``flicker`` set (the simplified frame ``k`` against the
    simplified frame ``k-1`` moved onto frame ``k`` by the registration, see
    :mod:`~torchmeshmetric.evaluation.flicker`): every :meth:`update` then takes ``simplified_k_minus_1`` too (the
    model's output for the previous frame), and :meth:`compute` returns a ``"flicker"`` entry. The choice is made
    once, at construction, so that every process of a DDP run holds the same states.

    Args:
        two_sided: also accumulate the reverse (reference → simplified) sets (default ``True``).
        flicker: also accumulate the ``flicker`` set (default ``False``; each update then needs
            ``simplified_k_minus_1``).
        registration_fn: registration function (default: the library's non-rigid registration); the old
            keyword ``register`` still works, with a ``DeprecationWarning``.
        registration_options: options of the default registration (``NonRigidOptions`` or its fields; run
            arguments such as a ``generator`` are passed on but not keyed, see
            :data:`~torchmeshmetric.evaluation.pipeline.RegistrationOptions`).
        backend: kernel backend of the distances and of the default registration (``"auto"``, ``"bvh"``, ...).
        kwargs: passed to :class:`torchmetrics.Metric`.

    Example:
        >>> import trimesh
        >>> sphere = trimesh.creation.icosphere(subdivisions=2)
        >>> coarse = trimesh.creation.icosphere(subdivisions=1)
        >>> metric = TemporalConsistency(registration_fn=lambda src, dst: src)
        >>> metric.update(coarse, sphere, sphere)
        >>> out = metric.compute()
        >>> sorted(out)
        ['reverse', 'surface_k', 'surface_k_minus_1', 'vertex_k', 'vertex_k_minus_1']
        >>> vertex_k = out["vertex_k"]
        >>> float(vertex_k["max"]) < 1e-12  # coarse icosphere vertices lie on the fine one
        True
        >>> stable = TemporalConsistency(flicker=True, registration_fn=lambda src, dst: src)
        >>> stable.update(coarse, sphere, sphere, simplified_k_minus_1=coarse)
        >>> flicker = stable.compute()["flicker"]
        >>> float(flicker["max"]) < 1e-12  # the same simplification twice: no flicker
        True
    """

    is_differentiable = False
    higher_is_better = False
    full_state_update = False
    peak: Tensor

    def __init__(
        self,
        *,
        two_sided: bool = True,
        registration_fn: RegisterFn | Any | None = None,
        registration_options: RegistrationOptions = None,
        backend: str = "auto",
        flicker: bool = False,
        **kwargs: Any,
    ) -> None:
        super().__init__(**kwargs)
        check_flag(two_sided, "two_sided")
        check_flag(flicker, "flicker")
        if registration_fn is not None and not callable(registration_fn):
            raise TypeError(f"registration_fn: expected a callable or None, found {type(registration_fn).__name__}")
        self.two_sided = two_sided
        self.registration_fn = registration_fn
        self.registration_options = registration_keywords(registration_options)
        self.registration_cache = RegistrationCache()
        self.backend = check_backend(backend)  # at construction, not at the first validation step
        # One index per reference mesh, found again by content: validating every epoch on the same frames builds
        # each reference's structure once.
        self.indexes = IndexCache(max_entries=64)
        self.measure_flicker = flicker
        self._set_names = SET_NAMES + ((FLICKER,) if flicker else ())
        for name in self._set_names:
            _FORWARD_STATES[name].add_to(self, sketch=None)
            if two_sided:
                _REVERSE_STATES[name].add_to(self, sketch=None)
        self.add_state("peak", default=torch.tensor(0.0, dtype=torch.float64), dist_reduce_fx="max")

    def update(
        self,
        simplified_k: MeshLike,
        original_k: MeshLike,
        original_k_minus_1: MeshLike,
        simplified_k_minus_1: MeshLike | None = None,
        *,
        precomputed_registration: Any = None,
    ) -> None:
        """Evaluate one simplified frame ``k`` against original frames ``k`` and ``k-1``.

        Args:
            simplified_k: the simplified frame ``k``.
            original_k: the original frame ``k``.
            original_k_minus_1: the original frame ``k-1``.
            simplified_k_minus_1: the simplified frame ``k-1``: required with ``flicker=True``, refused otherwise.
            precomputed_registration: frame ``k-1`` already registered onto frame ``k`` (as in
                :func:`~torchmeshmetric.evaluation.evaluate_pair`); default: registered here (cached). The old
                keyword ``registration`` still works, with a ``DeprecationWarning``.

        Raises:
            ValueError: ``simplified_k_minus_1`` missing with ``flicker=True``, or given with ``flicker=False``.
        """
        if self.measure_flicker and simplified_k_minus_1 is None:
            raise ValueError("simplified_k_minus_1: required by TemporalConsistency(flicker=True), found None")
        if not self.measure_flicker and simplified_k_minus_1 is not None:
            raise ValueError(
                "simplified_k_minus_1: given, but this metric was built with flicker=False "
                "(build it with TemporalConsistency(flicker=True) to measure the flicker set)"
            )
        result = evaluate_pair(
            simplified_k,
            original_k,
            original_k_minus_1,
            two_sided=self.two_sided,
            device=self.device,
            registration_fn=self.registration_fn,
            registration_options=self.registration_options,
            registration_cache=self.registration_cache,
            backend=self.backend,
            indexes=self.indexes,
            precomputed_registration=precomputed_registration,
            simplified_k_minus_1=simplified_k_minus_1,
        )
        for name in self._set_names:
            _FORWARD_STATES[name].update(self, result.distances[name], sketch=None, name=name)
            if self.two_sided:
                _REVERSE_STATES[name].update(self, result.reverse_distances[name], sketch=None, name=f"reverse {name}")
        peak: Tensor = self.peak
        self.peak = torch.maximum(peak, torch.tensor(result.peak, dtype=torch.float64, device=peak.device))

    def _setting_items(self) -> dict[str, object]:
        """The sets measured and the registration, as the registration cache identifies it.

        The library's registration by the options that differ from the defaults (equal options spelled differently
        are one setting); another ``registration_fn`` by its lasting name (a top-level function, a ``cache_key``) or,
        without one (a lambda, a partial), by the object itself
        (:func:`~torchmeshmetric.registration.cache.object_name`), and the options given to it. The ``backend``
        changes a registration only by rounding, and is left out as the cache leaves it out.
        """
        registration = registration_settings(self.registration_fn, self.registration_options)
        options = registration["options"]
        if isinstance(options, NonRigidOptions):
            # Against the evaluation's defaults (canonical sampling): a caller's {"sampling": "index"} is a setting.
            # canonical() leaves the default "index" out of its key, so it is put back to compare.
            defaults = NonRigidOptions(sampling=REGISTRATION_SAMPLING).canonical()
            given = {"sampling": "index", **options.canonical()}
            options = {k: v for k, v in given.items() if v != defaults[k]}
        return {
            **super()._setting_items(),
            "two_sided": self.two_sided,
            "flicker": self.measure_flicker,
            "registration_fn": None
            if self.registration_fn is None
            else registration["register"] or object_name(self.registration_fn),
            "registration_options": dict(sorted(options.items())),
        }

    def _statistics(self, states: DistanceStates, what: str) -> dict[str, Tensor]:
        return states.compute(self, sketch=None, what=what, peak=float(self.peak)).as_tensors()

    def _plot_result(self, result: Any) -> dict[str, Tensor]:
        """``plot()`` draws the nested result flattened: ``"surface_k/rmse"``, ``"reverse/vertex_k/max"``."""
        return flatten_statistics(result)  # type: ignore[return-value]

    def _plot_keys(self, result: dict[str, Tensor]) -> list[str]:
        """``plot()`` draws every set's RMSE by default (the others on request, e.g. ``keys=["flicker/max"]``)."""
        return [k for k in result if k.endswith("/rmse")]

    def compute(self) -> dict[str, Any]:
        """Pooled statistics: ``{set_name: {statistic: 0-dim tensor}}`` (+ ``"reverse"`` when two-sided).

        The sets are the four of the paper, plus ``"flicker"`` with ``flicker=True``.

        Raises:
            EmptyInputError: nothing was accumulated (no :meth:`update` since the last reset).
        """
        out: dict[str, Any] = {name: self._statistics(_FORWARD_STATES[name], name) for name in self._set_names}
        if self.two_sided:
            out["reverse"] = {
                name: self._statistics(_REVERSE_STATES[name], f"reverse {name}") for name in self._set_names
            }
        return out
