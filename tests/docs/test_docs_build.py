"""The docs site: every page is in the nav and exists; it builds strictly (warnings are errors).

A missing page or module is a failure; only missing docs tools (mkdocs, mkdocstrings) skip the build test.
"""

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]


def _nav_pages(nav):
    for item in nav:
        value = next(iter(item.values())) if isinstance(item, dict) else item
        if isinstance(value, list):
            yield from _nav_pages(value)
        else:
            yield value


def _missing():
    """Pages in the nav and documented modules that do not exist (a failure: every page is on main)."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    pages = [p for p in _nav_pages(config["nav"]) if not (ROOT / "docs" / p).is_file()]
    modules = [
        m
        for m in ("kernels", "stats", "data", "simplification", "registration", "evaluation", "viz")
        if importlib.util.find_spec(f"torchmeshmetric.{m}") is None
    ]
    return pages + [f"torchmeshmetric.{m}" for m in modules]


def test_nav_lists_every_page():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    listed = set(_nav_pages(config["nav"]))
    pages = {str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md")}
    assert pages - listed == set(), "pages missing from the mkdocs.yml nav"
    assert _missing() == [], "nav pages or documented modules do not exist"


def test_docs_build_strict(tmp_path):
    pytest.importorskip("mkdocs")  # the `test` extra; only a missing tool is a skip
    pytest.importorskip("mkdocstrings")
    missing = _missing()
    assert not missing, f"nav pages or documented modules do not exist: {', '.join(missing)}"
    r = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert (tmp_path / "site" / "index.html").is_file()
    shutil.rmtree(tmp_path / "site")
