"""Benchmarks: slamkit timed against a reference measured in the same run (raw GTSAM, a
per-particle Python loop, a default ``casadi.Opti`` build, heapq A*, pyastar2d, OMPL, a naive
nearest-neighbour ICP), one module per suite. ``ratio`` is always "how many times better than
the reference". Speed is measured here, never asserted in the test suite.

This layer sits beside ``experiments`` (it may import every algorithm package) and is the only
place besides ``backend``/``control`` that may import gtsam/casadi: its references are those
libraries used the plain way.
"""
