"""The identification's own exception class."""
from __future__ import annotations


class IdentifyError(ValueError):
    """A record or an option the identification cannot use; the message says what to pass."""
