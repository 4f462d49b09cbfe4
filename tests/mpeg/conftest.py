"""Locations of the outside oracle: mmetric's reference figures and the ``mm`` binary (both beside the checkout).

``../shared`` is the workplace's folder beside the checkout (``TORCHMESHMETRIC_SHARED`` points elsewhere, e.g. from
a git worktree); every test that reads it skips with a reason where it is absent. mmetric's own small test meshes
are shipped with the tests (:data:`MM_TESTS`), so the tests that only read them run in every clone.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("TORCHMESHMETRIC_SHARED", str(REPO.parent / "shared")))
MPEG_REF = SHARED / "reference" / "mpeg"
MM = SHARED / "tools" / "mmetric" / "mm"
MM_TESTS = REPO / "tests" / "data" / "mmetric"
"""mmetric's own small test meshes (BSD-3, tests/data/mmetric/LICENSE.md)."""
