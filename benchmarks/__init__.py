"""Speed benchmarks (``python -m benchmarks``): ratios against references measured in the
same run, never asserted in tests."""
