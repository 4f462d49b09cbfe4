"""Locations of the outside oracle: mmetric's reference figures and the ``mm`` binary (both beside the checkout)."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
MPEG_REF = REPO.parent / "shared" / "reference" / "mpeg"
MM = REPO.parent / "shared" / "tools" / "mmetric" / "mm"
