"""Benchmarks: throughput and cost-growth curves (``bench_*`` experiments, issue 13)."""
