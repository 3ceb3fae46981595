"""Benchmarks.  Each one times its subject against a baseline measured in the same run
(machines are shared and noisy, so only ratios mean anything), prints a table and
writes ``<out>/<name>.json``.  ``BENCHES`` maps a name to ``fn(out_dir, repeats)``,
which returns the path it wrote."""

import statistics
import time


def median_seconds(fn, repeats):
    """Median wall time of ``repeats`` calls of ``fn()`` after one warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def print_table(title, rows):
    """Print ``rows`` of (label, value, unit) under a title, aligned."""
    print(title)
    width = max(len(label) for label, _, _ in rows)
    for label, value, unit in rows:
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        print(f"  {label:<{width}}  {text} {unit}".rstrip())


BENCHES = {}
