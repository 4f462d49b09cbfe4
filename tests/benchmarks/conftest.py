"""Benchmark helpers: collect timings per (group, contender) and print one table of ratios per group."""

from __future__ import annotations

from collections import defaultdict

import pytest

TIMINGS: dict[str, dict[str, float]] = defaultdict(dict)
"""group -> contender -> best wall time in seconds (filled by the benchmarks)."""

OURS = "ours"


def _record(group: str, name: str, seconds: float) -> None:
    TIMINGS[group][name] = min(seconds, TIMINGS[group].get(name, float("inf")))


@pytest.fixture
def record():
    """``record(group, name, seconds)``: store a best time for the ratio tables (``name="ours"`` is the reference)."""
    return _record


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if not TIMINGS:
        return
    tr = terminalreporter
    tr.section("ratios: ours / peer (build + query, < 1 means ours is faster)")
    for group in sorted(TIMINGS):
        row = TIMINGS[group]
        ours = row.get(OURS)
        tr.write_line(f"{group}")
        for name, t in sorted(row.items(), key=lambda kv: kv[1]):
            ratio = f"{ours / t:7.2f}x" if ours is not None else "    n/a"
            tr.write_line(f"    {name:<24s} {t * 1e3:10.1f} ms   ours/peer {ratio}")
