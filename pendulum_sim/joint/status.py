"""The live one-line status on stderr and the summary printed at shutdown."""
from __future__ import annotations

import math
import sys
import time
from collections.abc import Mapping
from typing import TextIO

TTY_PERIOD = 0.2  # s between refreshes of the \r-refreshed line
PLAIN_PERIOD = 5.0  # s between plain lines when stderr is not a terminal


class StatusLine:
    """Write a status line: ``\\r``-refreshed on a terminal, a plain line now and then if not."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self._stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self._stream, 'isatty', lambda: False)())
        self._period = TTY_PERIOD if self.tty else PLAIN_PERIOD
        self._next = time.monotonic() + (0.0 if self.tty else self._period)
        self._width = 0

    def due(self, now: float) -> bool:
        """Return True when the line should be refreshed at monotonic time ``now``."""
        return now >= self._next

    def show(self, now: float, text: str) -> None:
        """Write ``text`` as the current status."""
        self._next = now + self._period
        if self.tty:
            pad = max(0, self._width - len(text))
            self._width = len(text)
            self._stream.write('\r' + text + ' ' * pad)
        else:
            self._stream.write(text + '\n')
        self._stream.flush()

    def finish(self) -> None:
        """End the refreshed line so what follows starts on a fresh line."""
        if self.tty and self._width:
            self._stream.write('\n')
            self._stream.flush()
            self._width = 0


def status_text(t: float, phi: float, energy: float, rtf: float, paused: bool) -> str:
    """Return the one-line status: simulated time, angle, energy, achieved real-time factor."""
    rtf_text = 'n/a' if math.isnan(rtf) else f'{rtf:.3f}'
    return (f'pendulum_node  t={t:10.3f} s  phi={phi:+.4f} rad  E={energy:.6f} J  '
            f'RTF={rtf_text}' + ('  [paused]' if paused else ''))


def summary_text(fields: Mapping[str, object]) -> str:
    """Return the shutdown summary, one ``key: value`` per line."""
    width = max(len(k) for k in fields)
    lines = ['pendulum_node summary:']
    for key, value in fields.items():
        text = f'{value:.6g}' if isinstance(value, float) else str(value)
        lines.append(f'  {key:<{width}}  {text}')
    return '\n'.join(lines)
