"""``SettingsMetric``: a ``torchmetrics.Metric`` that refuses to merge the states of another configuration.

torchmetrics' ``merge_state`` checks the class of an incoming metric, not its options: it pooled the exact distances
of ``MeshSurfaceDistance()`` and the sampled ones of ``MeshSurfaceDistance(surface_samples=20)`` into one set, and
dropped the states that one configuration has and the other lacks (``TemporalConsistency``'s reverse and flicker
sets). A :class:`SettingsMetric` lists, in :meth:`~SettingsMetric._setting_items`, the options that change what its
states accumulate, and :meth:`~SettingsMetric.merge_state` refuses a metric of other settings, or a state dict of
other states, in words. Options that only ``compute()`` reads (``ddof``, ``peak``) are left out: the merged states
are the same measurement. So is the kernel ``backend``, which changes a distance only by rounding (as the
registration cache leaves it out of its key).
"""

from __future__ import annotations

from typing import Any

from torch import Tensor
from torchmetrics import Metric

__all__ = ["SettingsMetric"]


class SettingsMetric(Metric):
    """A ``torchmetrics.Metric`` whose settings keep it out of other configurations' merges.

    A subclass overrides :meth:`_setting_items` (calling the parent's) to add the options that change its states.
    See the module docstring.
    """

    def _setting_items(self) -> dict[str, object]:
        """The options that change what the states accumulate, by name (``compute()``-only options left out)."""
        return {}

    def _settings(self) -> str:
        """``ClassName(option=value, ...)``: the settings, as messages show them."""
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self._setting_items().items())})"

    def merge_state(self, incoming_state: dict[str, Any] | Metric) -> None:
        """Torchmetrics' ``merge_state``, refusing what :meth:`_check_incoming` refuses.

        Raises:
            ValueError: a metric of another class or settings, or a dict whose states are not this metric's.
        """
        self._check_incoming(incoming_state)
        super().merge_state(incoming_state)

    def _check_incoming(self, incoming_state: dict[str, Any] | Metric) -> None:
        """Refuse a metric of other settings, or a dict of other states.

        torchmetrics dropped the states it did not know, and printed every tensor of the dict when one of its own was
        missing.

        Raises:
            ValueError: what it refuses.
        """
        if isinstance(incoming_state, SettingsMetric):
            if incoming_state._settings() != self._settings():
                raise ValueError(
                    f"incoming_state: {incoming_state._settings()} cannot merge into {self._settings()}: their states "
                    "hold different measurements; merge metrics built with the same options"
                )
            return
        if not isinstance(incoming_state, dict):
            return  # torchmetrics refuses it
        missing = [name for name in self._defaults if name not in incoming_state]
        unknown = [name for name in incoming_state if name not in self._defaults]
        if missing or unknown:
            lists = [f"{what} {_some(names)}" for what, names in (("missing", missing), ("unknown", unknown)) if names]
            raise ValueError(f"incoming_state: expected the states of {self._settings()}, found {'; '.join(lists)}")
        for name, default in self._defaults.items():
            found = incoming_state[name]
            if isinstance(default, Tensor) and not (isinstance(found, Tensor) and found.shape == default.shape):
                shape = tuple(found.shape) if isinstance(found, Tensor) else type(found).__name__
                raise ValueError(
                    f"incoming_state: state {name!r} of {self._settings()} expected shape {tuple(default.shape)}, "
                    f"found {shape}"
                )


def _some(names: list[str], shown: int = 3) -> str:
    """The first ``shown`` of ``names`` and how many more (a message stays a line)."""
    more = f" and {len(names) - shown} more" if len(names) > shown else ""
    return f"{len(names)} ({', '.join(names[:shown])}{more})"
