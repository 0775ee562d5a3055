"""End the process with a given exit code if a stretch of work outlasts a deadline.

Python cannot time out a call into C that keeps the GIL: a watchdog thread written in Python
never runs while the call lasts, and a signal handler runs only when the call returns. The
deadline here is a POSIX timer whose expiry the C library hands to a thread of its own
(``timer_create`` with ``SIGEV_THREAD``), and that thread's function is ``_exit`` itself, given
the exit code as the timer's value (``union sigval`` travels in the first integer register on
the x86-64 and AArch64 Linux ABIs, where ``_exit`` reads its ``int``). No Python code runs when
it fires, so it works whatever the interpreter is doing. The process ends as ``_exit`` ends it:
no destructors, no buffered output flushed; :func:`exit_deadline` flushes ``sys.stdout`` and
``sys.stderr`` before it arms the timer.

The package uses it around rclpy's teardown (:func:`pendulum_sim.dds.shut_down`). Where the
timer cannot be made (not Linux, no ``timer_create``), :func:`exit_deadline` runs the work
without a deadline.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import sys
from collections.abc import Iterator
from contextlib import contextmanager

_CLOCK_MONOTONIC = 1
_SIGEV_THREAD = 2


class _SigVal(ctypes.Union):
    _fields_ = [('sival_int', ctypes.c_int), ('sival_ptr', ctypes.c_void_p)]


class _SigEvent(ctypes.Structure):
    """glibc's ``struct sigevent`` (64 bytes on 64-bit Linux)."""

    _fields_ = [('sigev_value', _SigVal), ('sigev_signo', ctypes.c_int),
                ('sigev_notify', ctypes.c_int), ('sigev_notify_function', ctypes.c_void_p),
                ('sigev_notify_attributes', ctypes.c_void_p),
                ('_pad', ctypes.c_byte * (64 - 32))]


class _TimeSpec(ctypes.Structure):
    _fields_ = [('tv_sec', ctypes.c_long), ('tv_nsec', ctypes.c_long)]


class _ITimerSpec(ctypes.Structure):
    _fields_ = [('it_interval', _TimeSpec), ('it_value', _TimeSpec)]


def _libc() -> ctypes.CDLL | None:
    """Return the C library holding ``timer_create`` and ``_exit``, or None where there is none."""
    if not sys.platform.startswith('linux') or ctypes.sizeof(ctypes.c_void_p) != 8:
        return None
    for name in (None, ctypes.util.find_library('rt')):  # glibc >= 2.34 has it in libc
        try:
            lib = ctypes.CDLL(name, use_errno=True)
        except OSError:
            continue
        if hasattr(lib, 'timer_create') and hasattr(lib, '_exit'):
            return lib
    return None


def _arm(lib: ctypes.CDLL, code: int, seconds: float) -> ctypes.c_void_p | None:
    """Start a one-shot timer that calls ``_exit(code)`` after ``seconds``; None if refused."""
    event = _SigEvent()
    event.sigev_value.sival_int = code
    event.sigev_notify = _SIGEV_THREAD
    event.sigev_notify_function = ctypes.cast(lib._exit, ctypes.c_void_p).value
    timer = ctypes.c_void_p()
    if lib.timer_create(_CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(timer)) != 0:
        return None
    whole = int(seconds)
    spec = _ITimerSpec(it_value=_TimeSpec(whole, max(1, int((seconds - whole) * 1e9))))
    if lib.timer_settime(timer, 0, ctypes.byref(spec), None) != 0:
        lib.timer_delete(timer)
        return None
    return timer


@contextmanager
def exit_deadline(code: int, seconds: float) -> Iterator[bool]:
    """Run the ``with`` block; if it is still running after ``seconds``, end the process.

    Parameters
    ----------
    code : int
        The exit code the process ends with when the deadline passes (0-255).
    seconds : float
        The deadline, > 0, counted on the monotonic clock from entering the block.

    Yields
    ------
    bool
        True when the deadline is armed, False where the platform has no such timer (the block
        then runs without one). Leaving the block, normally or by an exception, disarms it.
    """
    if not 0 <= code <= 255:
        raise ValueError(f'exit code must be in 0..255, got {code}')
    if not seconds > 0:
        raise ValueError(f'deadline must be > 0 s, got {seconds}')
    sys.stdout.flush()
    sys.stderr.flush()
    lib = _libc()
    timer = _arm(lib, code, seconds) if lib is not None else None
    try:
        yield timer is not None
    finally:
        if lib is not None and timer is not None:
            lib.timer_delete(timer)
