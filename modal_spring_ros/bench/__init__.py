"""Benchmarks: step cost, the live stream, and speed against accuracy (with charts)."""
