"""Build the docs site strictly (warnings are errors) when the docs tools are installed (the `test` extra)."""

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]

pytest.importorskip("mkdocs")
pytest.importorskip("mkdocstrings")


def _nav_pages(nav):
    for item in nav:
        value = next(iter(item.values())) if isinstance(item, dict) else item
        if isinstance(value, list):
            yield from _nav_pages(value)
        else:
            yield value


def _missing():
    """Pages and modules written by other issues that have not been merged into this branch yet."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    pages = [p for p in _nav_pages(config["nav"]) if not (ROOT / "docs" / p).is_file()]
    modules = [
        m
        for m in ("stats", "data", "simplification", "registration")
        if importlib.util.find_spec(f"torchmeshmetric.{m}") is None
    ]
    return pages + [f"torchmeshmetric.{m}" for m in modules]


def test_docs_build_strict(tmp_path):
    missing = _missing()
    if missing:
        pytest.skip(f"docs of other issues not merged yet: {', '.join(missing)}")
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
