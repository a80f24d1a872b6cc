"""Benchmarks for galileo_async: every figure is printed next to a baseline from the same run."""
