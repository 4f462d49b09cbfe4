"""How far the pinned demo report moves between CPU personalities: the measurement behind the golden's tolerance.

Runs the pinned demo (tests/evaluation/test_report_pinned.py's arguments) in a new process under the machine's own
kernels and under each personality of tests/cpu_personalities.py, then prints, per personality, how many floats of
report.json differ, the largest relative differences and whether report.md is the same text. Run::

    python -m tests.evaluation.report_personalities
"""

from __future__ import annotations

import json
import math

from tests.cpu_personalities import OTHER_CPUS, run_as
from tests.evaluation.report_stability import _floats

_RUN = """
import json, sys, tempfile
from pathlib import Path
from tests.evaluation.test_report_pinned import run_demo
with tempfile.TemporaryDirectory() as tmp:
    texts = run_demo(Path(tmp) / "demo")
sys.stdout.write("\\n" + json.dumps(texts))
"""


def _report(personality: dict[str, str]) -> dict[str, str]:
    return json.loads(run_as(personality, _RUN).rsplit("\n", 1)[1])


def main() -> None:
    base = _report({})
    base_floats = dict(_floats(json.loads(base["report.json"])))
    for name, personality in OTHER_CPUS.items():
        got = _report(personality)
        floats = dict(_floats(json.loads(got["report.json"])))
        diffs = sorted(
            (abs(floats[k] - b) / max(abs(b), abs(floats[k])), k)
            for k, b in base_floats.items()
            if math.isfinite(b) and floats[k] != b
        )
        same = {n: got[n] == base[n] for n in ("report.md", "report.csv")}
        print(f"{name}: {len(diffs)} of {len(base_floats)} floats differ; identical text: {same}")
        for change, key in diffs[-5:]:
            print(f"  {change:.1e} {key}")


if __name__ == "__main__":
    main()
