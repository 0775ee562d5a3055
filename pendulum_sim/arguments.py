"""Argument types shared by the command-line programs (argparse ``type=`` callables)."""
from __future__ import annotations

import argparse


def positive_int(text: str) -> int:
    """Parse a whole number >= 1, or say what was given (argparse prefixes the option)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be an integer >= 1, got {text!r}') from None
    if value < 1:
        raise argparse.ArgumentTypeError(f'must be an integer >= 1, got {text!r}')
    return value
