"""slamkit: mobile-robot estimation written as optimisation.

Layers (inner first) are listed in ARCHITECTURE.md; ``tests/test_layers.py`` enforces the
import arrows.
"""

__version__ = "0.1.0"
