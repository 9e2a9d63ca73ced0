"""A newcomer's first hour (issue 42): what ``brdflab bench`` says about the machine its figures come from."""

from __future__ import annotations

import os

from brdflab import benchmarking as bench


def test_bench_says_the_cpu_model_and_cores_first():
    said = []
    assert bench.run_suite([], 1, 1, 1, None, say=said.append) == []
    assert said and said[0].startswith(f"machine: {bench.cpu_model()}, {os.cpu_count()} cores")
    assert bench.cpu_model() and bench.cpu_model() != "unknown CPU" or not os.path.exists("/proc/cpuinfo")
