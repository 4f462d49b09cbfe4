"""Temporary: skip doctests of modules that need ``torchmeshmetric.stats`` until issue 3 is merged."""

import importlib.util

collect_ignore = []
if importlib.util.find_spec("torchmeshmetric.stats") is None:  # issue 3 not merged into this branch yet
    collect_ignore = ["pipeline.py", "metric.py"]
