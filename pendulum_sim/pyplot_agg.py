"""matplotlib.pyplot on the non-interactive Agg backend, imported on first use.

The one way every figure of the package (the reports, the test bench's closed-loop figure, a
campaign's figures) gets pyplot: matplotlib is optional, and a headless run must never open a
window.
"""
from __future__ import annotations

from typing import Any


def pyplot() -> Any:
    """Return matplotlib.pyplot on the non-interactive Agg backend."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt
