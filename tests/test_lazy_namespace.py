"""The lazy package namespaces keep every public name: ``__all__``, ``dir()``, ``from ... import`` and types.

Each package's ``__init__.pyi`` lists its names; ``torchmeshmetric/_lazy.py`` serves them on first use.
"""

from __future__ import annotations

import ast
import importlib
import os
import pkgutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import torchmeshmetric

PACKAGE = Path(torchmeshmetric.__file__).parent
SUBPACKAGES = (m.name for m in pkgutil.walk_packages([str(PACKAGE)], "torchmeshmetric.") if m.ispkg)
PACKAGES = ["torchmeshmetric", *sorted(p for p in SUBPACKAGES if p != "torchmeshmetric.cli")]


def _stub(package: str) -> ast.Module:
    path = PACKAGE.parent / package.replace(".", "/") / "__init__.pyi"
    return ast.parse(path.read_text())


def test_every_package_but_the_cli_is_lazy():
    assert len(PACKAGES) == 17  # the root and its 16 subpackages with stubs (native, temporal, mpeg's four rooms)
    for package in PACKAGES:
        assert (PACKAGE.parent / package.replace(".", "/") / "__init__.pyi").is_file(), package


@pytest.mark.parametrize("package", PACKAGES)
def test_every_name_of_all_loads_and_is_in_dir_and_star_import(package):
    module = importlib.import_module(package)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no name of __all__ is a deprecated one
        objects = {name: getattr(module, name) for name in module.__all__}
    assert len(set(module.__all__)) == len(module.__all__)
    assert set(module.__all__) <= set(dir(module))
    namespace: dict[str, object] = {}
    exec(f"from {package} import *", namespace)
    assert {k: v for k, v in namespace.items() if k != "__builtins__"} == objects


@pytest.mark.parametrize("package", PACKAGES)
def test_the_stub_imports_each_name_from_the_module_that_serves_it(package):
    """The types mypy reads (the stub's imports) are the objects served at run time."""
    module = importlib.import_module(package)
    for node in _stub(package).body:
        if not isinstance(node, ast.ImportFrom):
            continue
        source = importlib.import_module(f"{package}.{node.module}" if node.module else package)
        for alias in node.names:
            want = getattr(source, alias.name) if node.module else importlib.import_module(f"{package}.{alias.name}")
            assert getattr(module, alias.asname or alias.name) is want, (package, alias.name)


def test_the_root_serves_the_whole_data_kernel_and_metric_packages():
    for sub in (torchmeshmetric.data, torchmeshmetric.kernels, torchmeshmetric.metrics):
        assert set(sub.__all__) <= set(torchmeshmetric.__all__), sub.__name__
        for name in sub.__all__:
            assert getattr(torchmeshmetric, name) is getattr(sub, name)


def test_a_function_named_like_its_module_stays_the_function():
    # mpeg/comparison/mpeg_metrics.py defines mpeg_metrics; importing the module must not replace the function of
    # its room (mpeg.comparison) nor of mpeg.
    importlib.import_module("torchmeshmetric.mpeg.comparison.mpeg_metrics")
    module = sys.modules["torchmeshmetric.mpeg.comparison.mpeg_metrics"]
    for package in (torchmeshmetric.mpeg, torchmeshmetric.mpeg.comparison):
        assert callable(package.mpeg_metrics) and package.mpeg_metrics is module.mpeg_metrics, package.__name__
    assert torchmeshmetric.metrics.mesh_surface_distance_loss.__name__ == "mesh_surface_distance_loss"


def test_unknown_names_are_attribute_errors():
    with pytest.raises(AttributeError, match="module 'torchmeshmetric' has no attribute 'no_such_name'"):
        _ = torchmeshmetric.no_such_name
    assert not hasattr(torchmeshmetric.kernels, "no_such_name")


def test_eager_import_loads_every_name_at_once():
    """``EAGER_IMPORT=1`` (lazy_loader's switch) imports all names of a package at import: a broken one fails."""
    code = "import torchmeshmetric, sys; print('torchmetrics' in sys.modules)"
    r = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env={**os.environ, "EAGER_IMPORT": "1", "PYTHONPATH": str(PACKAGE.parent)},
        check=False,
    )
    assert r.returncode == 0 and r.stdout.strip() == "True", r.stderr


def test_a_name_is_bound_when_its_module_is_imported_so_a_later_patch_does_not_leak():
    """As with eager imports: the package's name is the object its module held when imported, not when first used."""
    code = (
        "import torchmeshmetric.evaluation.pipeline as pipeline\n"
        "original = pipeline.default_register\n"
        "pipeline.default_register = 'patched'  # what monkeypatch.setattr('...pipeline.default_register') does\n"
        "import torchmeshmetric.evaluation as evaluation\n"
        "assert evaluation.default_register is original, evaluation.default_register\n"
    )
    env = {**os.environ, "PYTHONPATH": str(PACKAGE.parent)}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=False)
    assert r.returncode == 0, r.stderr
