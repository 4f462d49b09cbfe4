"""``SettingsMetric``: a ``torchmetrics.Metric`` that two configurations of one class never share.

torchmetrics puts metrics of a ``MetricCollection`` into one compute group when, after the first update, their states
have the same names and ``allclose`` values; later updates then reach the group's first member only, and every member
computes from that member's states. Two configurations of one class have the same state names, and after an empty
first batch the same values: ``MeshSurfaceDistance(surface_samples=50)`` reported the exact
``MeshSurfaceDistance()``'s figures. ``merge_state`` likewise pooled exact and sampled distances into one set, and
dropped the states that one configuration has and the other lacks (the reverse or flicker sets).

A :class:`SettingsMetric` lists, in :meth:`~SettingsMetric._setting_items`, the options that change what its states
accumulate, and holds their SHA-256 digest as one more state, ``settings_digest`` (32 float64 bytes; ``"max"``
across processes, which all hold the same; never written to a ``state_dict``, whose keys stay what they were). A
``state_dict`` that holds states (``persistent(True)``) also holds the settings they were accumulated with, as UTF-8
bytes under ``states_settings``, and ``load_state_dict`` refuses them into a metric of other settings as
``merge_state`` does (it pooled sampled and exact distances in silence: found by review); a ``state_dict`` without
states (torchmetrics' default) keeps no key, and one written before (without the key) loads as it did.
Two configurations then never hold equal states, so torchmetrics never groups them, and :meth:`~SettingsMetric.
merge_state` refuses a metric, or a state dict, of another configuration in words. Options that only ``compute()``
reads (``ddof``, ``peak``) are left out: each member of a group computes with its own. So is the kernel
``backend``, which changes a distance only by rounding (as the registration cache leaves it out of its key).
"""

from __future__ import annotations

import hashlib
from abc import ABCMeta
from typing import Any

import torch
from torch import Tensor
from torchmetrics import Metric

__all__ = ["SETTINGS_DIGEST", "SETTINGS_KEY", "SettingsMetric"]

#: The name of the state that holds the digest of a metric's settings.
SETTINGS_DIGEST = "settings_digest"

#: The ``state_dict`` key (after the metric's prefix) of the settings its states were accumulated with.
SETTINGS_KEY = "states_settings"


class _RecordsSettings(ABCMeta):
    """The metaclass of :class:`SettingsMetric`: records the settings once the whole constructor chain has run.

    A base class's ``__init__`` cannot: every subclass calls it first (``nn.Module`` needs that) and sets its own
    options after it.
    """

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        metric = super().__call__(*args, **kwargs)
        metric._record_settings()
        return metric


class SettingsMetric(Metric, metaclass=_RecordsSettings):
    """A ``torchmetrics.Metric`` whose settings keep it out of other configurations' compute groups and merges.

    A subclass overrides :meth:`_setting_items` (calling the parent's) to add the options that change its states.
    See the module docstring.
    """

    def _setting_items(self) -> dict[str, object]:
        """The options that change what the states accumulate, by name (``compute()``-only options left out)."""
        return {}

    def _settings(self) -> str:
        """``ClassName(option=value, ...)``: the settings, as messages show them and as the digest hashes them."""
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self._setting_items().items())})"

    def _record_settings(self) -> None:
        digest = torch.tensor(list(hashlib.sha256(self._settings().encode()).digest()), dtype=torch.float64)
        self.add_state(SETTINGS_DIGEST, default=digest, dist_reduce_fx="max", persistent=False)

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Torchmetrics' unpickling, the settings recorded for a metric pickled before they were."""
        super().__setstate__(state)
        if SETTINGS_DIGEST not in self._defaults:
            self._record_settings()

    def persistent(self, mode: bool = False) -> None:
        """Torchmetrics' ``persistent``, the settings digest left out of the ``state_dict`` whatever ``mode``.

        The digest is the constructor's, not an accumulation: checkpoints keep the keys they had before it existed,
        and load into a metric built with any options as they did.
        """
        super().persistent(mode)
        self._persistent[SETTINGS_DIGEST] = False

    def state_dict(  # type: ignore[override]  # torchmetrics' signature
        self, destination: dict[str, Any] | None = None, prefix: str = "", keep_vars: bool = False
    ) -> dict[str, Any]:
        """Torchmetrics' ``state_dict``, with the settings (UTF-8 bytes, a uint8 tensor) where it holds states."""
        out: dict[str, Any] = super().state_dict(destination=destination, prefix=prefix, keep_vars=keep_vars)
        if any(self._persistent[name] for name in self._defaults if name != SETTINGS_DIGEST):
            out[prefix + SETTINGS_KEY] = torch.tensor(list(self._settings().encode()), dtype=torch.uint8)
        return out

    def _load_from_state_dict(
        self,
        state_dict: dict,
        prefix: str,
        local_metadata: dict,
        strict: bool,
        missing_keys: list[str],
        unexpected_keys: list[str],
        error_msgs: list[str],
    ) -> None:
        """Torchmetrics' loading, refusing states accumulated with other settings (before any is loaded).

        Raises:
            ValueError: the ``state_dict`` names other settings than this metric's.
        """
        written = state_dict.pop(prefix + SETTINGS_KEY, None)
        if written is not None:
            found = bytes(written.tolist()).decode() if isinstance(written, Tensor) else repr(written)
            if found != self._settings():
                raise ValueError(
                    f"state_dict: the states of {found} cannot load into {self._settings()}: their states hold "
                    "different measurements; load them into a metric built with the same options"
                )
        super()._load_from_state_dict(
            state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys, error_msgs
        )

    def merge_state(self, incoming_state: dict[str, Any] | Metric) -> None:
        """Torchmetrics' ``merge_state``, refusing what :meth:`_check_incoming` refuses.

        Raises:
            ValueError: a metric of another class or settings, or a dict whose states are not this metric's.
        """
        if isinstance(incoming_state, dict) and SETTINGS_DIGEST not in incoming_state:
            # A dict written before the digest existed (or by hand): its states' names and shapes are all there is.
            incoming_state = {**incoming_state, SETTINGS_DIGEST: getattr(self, SETTINGS_DIGEST)}
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
        digest = incoming_state[SETTINGS_DIGEST]
        if not isinstance(digest, Tensor) or digest.tolist() != getattr(self, SETTINGS_DIGEST).tolist():
            raise ValueError(
                f"incoming_state: the states of a metric built with other options cannot merge into "
                f"{self._settings()} (its {SETTINGS_DIGEST} differs)"
            )
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
