"""Benchmarks behind ``wovenskin bench``: they print measured figures and ratios."""
