"""The benchmarks' code runs and measures what it says (figures are not checked)."""
