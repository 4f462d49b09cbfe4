import sys
from importlib import metadata
from pathlib import Path

import torchmeshmetric
from torchmeshmetric import _version
from torchmeshmetric.evaluation import reports

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

PYPROJECT = Path(__file__).resolve().parent.parent / "pyproject.toml"


def test_one_version_everywhere():
    declared = tomllib.loads(PYPROJECT.read_text())["project"]["version"]
    assert torchmeshmetric.__version__ == _version.__version__ == declared
    assert reports.__version__ == declared  # what report_dict writes


def test_source_checkout_reads_pyproject(monkeypatch):
    def not_installed(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(_version.metadata, "version", not_installed)
    assert _version._read_version() == tomllib.loads(PYPROJECT.read_text())["project"]["version"]


def test_no_version_anywhere(monkeypatch, tmp_path):
    def not_installed(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(_version.metadata, "version", not_installed)
    monkeypatch.setattr(_version, "__file__", str(tmp_path / "pkg" / "_version.py"))
    assert _version._read_version() == "0+unknown"
