"""Writing a report folder: Markdown summary, CSV tables, progress on stderr."""
from __future__ import annotations

import csv
import math
import os
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

from .errors import ReportError

Row = Mapping[str, Any]


def prepare_out_dir(out: str | os.PathLike[str], force: bool = False) -> Path:
    """Create the output folder, refusing an existing non-empty one unless ``force``."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise ReportError(f'--out {str(path)!r} exists and is not a directory')
    if path.is_dir() and any(path.iterdir()) and not force:
        raise ReportError(f'--out {str(path)!r} is not empty; use --force to write into it')
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ReportError(f'--out {str(path)!r} cannot be created: {exc.strerror}') from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise ReportError(f'--out {str(path)!r} is not writable')
    return path


def fmt(value: Any, digits: int = 3) -> str:
    """Format a table cell: floats in short scientific or fixed notation, the rest as str."""
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    if isinstance(value, float):
        if math.isnan(value):
            return '–'
        if math.isinf(value):
            return 'inf' if value > 0 else '-inf'
        if value == 0.0:
            return '0'
        if 1e-3 <= abs(value) < 1e4:
            return f'{value:.{digits}g}'
        return f'{value:.{max(digits - 1, 1)}e}'
    return str(value)


def write_csv(path: Path, rows: Sequence[Row], columns: Sequence[str] | None = None) -> Path:
    """Write rows (dicts) as a CSV table with a header; floats at full precision (repr)."""
    cols = list(columns) if columns is not None else _columns(rows)
    with path.open('w', newline='', encoding='utf-8') as fh:
        writer = csv.writer(fh)
        writer.writerow(cols)
        for row in rows:
            writer.writerow([_csv_cell(row.get(c, '')) for c in cols])
    return path


def markdown_table(rows: Sequence[Row], columns: Sequence[str],
                   headers: Sequence[str] | None = None, digits: int = 3) -> str:
    """Return a GitHub Markdown table of ``rows`` restricted to ``columns``."""
    head = list(headers) if headers is not None else list(columns)
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '|'.join('---' for _ in head) + '|']
    for row in rows:
        lines.append('| ' + ' | '.join(fmt(row.get(c, ''), digits) for c in columns) + ' |')
    return '\n'.join(lines)


def _columns(rows: Iterable[Row]) -> list[str]:
    cols: list[str] = []
    for row in rows:
        for key in row:
            if key not in cols:
                cols.append(key)
    return cols


def _csv_cell(value: Any) -> str:
    if isinstance(value, bool):
        return str(int(value))
    if isinstance(value, float):
        return repr(value)
    return str(value)


class Progress:
    """Print one line per finished item on stderr, with the elapsed time and an ETA."""

    def __init__(self, label: str, total: int, stream: IO[str] | None = None,
                 enabled: bool = True) -> None:
        self.label = label
        self.total = max(int(total), 1)
        self.done = 0
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.start = time.perf_counter()

    def tick(self, what: str) -> None:
        """Record one finished item and print its line."""
        self.done += 1
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        eta = elapsed / self.done * (self.total - self.done)
        print(f'[{self.label} {self.done}/{self.total}] {what}  elapsed {elapsed:.1f} s'
              f'  ETA {eta:.1f} s', file=self.stream, flush=True)


class Summary:
    """Collect Markdown sections and write them as ``summary.md`` (or append to one)."""

    def __init__(self, title: str) -> None:
        self.parts: list[str] = [f'# {title}\n']

    def section(self, heading: str, *paragraphs: str, level: int = 2) -> None:
        """Add a heading and its paragraphs."""
        self.parts.append(f'{"#" * level} {heading}\n')
        for para in paragraphs:
            self.parts.append(para.rstrip() + '\n')

    def text(self) -> str:
        """Return the whole summary as Markdown."""
        return '\n'.join(self.parts)

    def write(self, path: Path) -> Path:
        """Write the summary to ``path``."""
        path.write_text(self.text(), encoding='utf-8')
        return path
