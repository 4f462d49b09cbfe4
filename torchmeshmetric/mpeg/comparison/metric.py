"""A torchmetrics metric that logs MPEG D1/D2 PSNR in a validation loop (sibling of ``TemporalConsistency``)."""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import Tensor

from torchmeshmetric._checks import EmptyInputError, check_int
from torchmeshmetric.metrics._plot import StatisticsPlot
from torchmeshmetric.metrics._settings import SettingsMetric
from torchmeshmetric.mpeg.comparison.mpeg_metrics import Sampling, mpeg_metrics
from torchmeshmetric.mpeg.core.textured_mesh import TexturedMesh
from torchmeshmetric.structures import MeshLike

__all__ = ["MpegPSNR"]

_KEYS = ("d1_psnr", "d2_psnr")


class MpegPSNR(StatisticsPlot, SettingsMetric):
    """Mean per-frame MPEG D1 and D2 PSNR (mmetric's figures) over every mesh pair seen, DDP-synchronised.

    Each :meth:`update` compares one distorted mesh (``preds``) with its reference (``target``) by
    :func:`mpeg_metrics`; :meth:`compute` returns the CTC average (mean of per-frame PSNR; frames with infinite PSNR,
    i.e. identical meshes, are left out and counted in ``*_inf_frames``; ``inf`` if every frame is identical).

    Two metrics built with other ``sampling`` or ``grid_size`` never share a ``MetricCollection`` compute group, and
    ``merge_state`` refuses to pool them (see :class:`~torchmeshmetric.metrics._settings.SettingsMetric`).

    Args:
        sampling: ``"grid"`` (CTC) or ``"mesh"``.
        grid_size: grid steps (grid mode; smaller is faster for a validation loop).
        **kwargs: forwarded to :class:`torchmetrics.Metric`.

    Example:
        >>> import trimesh
        >>> m = MpegPSNR(sampling="mesh")
        >>> a = trimesh.creation.icosphere(2)
        >>> m.update(a.copy().apply_scale(1.01), a)
        >>> m.update(a, a)
        >>> out = m.compute()
        >>> round(out["d1_psnr"].item(), 2), out["d1_psnr_inf_frames"].item()
        (55.56, 1.0)
    """

    full_state_update = False
    higher_is_better = True

    def _plot_keys(self, result: dict[str, Tensor]) -> list[str]:
        """``plot()`` draws the two PSNRs (dB) as bars (the ``*_inf_frames`` counts on request)."""
        return list(_KEYS)

    def __init__(self, sampling: Sampling = "grid", grid_size: int = 1024, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        if sampling not in ("grid", "mesh"):
            raise ValueError(f"sampling: expected 'grid' or 'mesh', found {sampling!r}")
        grid_size = check_int(grid_size, "grid_size", 2)
        self.sampling: Sampling = sampling
        self.grid_size = grid_size
        for key in _KEYS:
            self.add_state(f"{key}_sum", torch.tensor(0.0, dtype=torch.float64), dist_reduce_fx="sum")
            self.add_state(f"{key}_finite", torch.tensor(0.0, dtype=torch.float64), dist_reduce_fx="sum")
            self.add_state(f"{key}_inf", torch.tensor(0.0, dtype=torch.float64), dist_reduce_fx="sum")

    def _setting_items(self) -> dict[str, object]:
        """The sampling, and the grid's size in grid mode (the mesh mode reads none)."""
        grid: dict[str, object] = {"grid_size": self.grid_size} if self.sampling == "grid" else {}
        return {**super()._setting_items(), "sampling": self.sampling, **grid}

    def update(self, preds: MeshLike | TexturedMesh, target: MeshLike | TexturedMesh) -> None:
        """Add one frame: ``preds`` (distorted) against ``target`` (reference)."""
        r = mpeg_metrics(
            target, preds, sampling=self.sampling, grid_size=self.grid_size, names=("target", "preds")
        ).symmetric
        for key, value in (("d1_psnr", r.d1_psnr), ("d2_psnr", r.d2_psnr)):
            if math.isfinite(value):
                setattr(self, f"{key}_sum", getattr(self, f"{key}_sum") + value)
                setattr(self, f"{key}_finite", getattr(self, f"{key}_finite") + 1)
            elif value > 0:
                setattr(self, f"{key}_inf", getattr(self, f"{key}_inf") + 1)

    def compute(self) -> dict[str, Tensor]:
        """``{"d1_psnr", "d2_psnr", "d1_psnr_inf_frames", "d2_psnr_inf_frames"}`` (float64 scalars).

        Raises:
            EmptyInputError: no frame was accumulated (no :meth:`update` since the last reset, on any process): the
                mean PSNR of no frame is undefined, and a NaN would be logged silently.
        """
        if all(float(getattr(self, f"{key}_finite") + getattr(self, f"{key}_inf")) == 0 for key in _KEYS):
            raise EmptyInputError(
                f"{type(self).__name__}.compute: no frame was accumulated; call update() with a mesh pair first"
            )
        out: dict[str, Tensor] = {}
        for key in _KEYS:
            s, n, inf = getattr(self, f"{key}_sum"), getattr(self, f"{key}_finite"), getattr(self, f"{key}_inf")
            if n > 0:
                out[key] = s / n
            else:
                out[key] = torch.tensor(math.inf if inf > 0 else math.nan, dtype=torch.float64)
            out[f"{key}_inf_frames"] = inf.clone()
        return out
