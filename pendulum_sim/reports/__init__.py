"""Reports: error against run time, stability on stiff and extreme cases, the paper's figures.

Each report is a library function that writes a folder (``summary.md``, CSV tables, PNG figures);
``pendulum_report`` (``cli.py``) is the thin command line over them.
"""
from __future__ import annotations

from .errors import ReportError

__all__ = ['ReportError']
