"""User-facing errors.

Everything a user can cause (bad file, bad option, inconsistent data under ``--strict``)
raises :class:`IvslamError`; the CLI prints its message on one line and exits non-zero,
with a traceback only under ``--debug``.
"""

from __future__ import annotations

from pathlib import Path


class IvslamError(Exception):
    """An error with a one-line message meant for the user."""

    exit_code = 2

    def __init__(self, message: str, path: str | Path | None = None):
        self.path = None if path is None else str(path)
        super().__init__(f"{self.path}: {message}" if self.path else message)


class LogError(IvslamError):
    """A log cannot be read: corrupt, truncated, empty, unknown format, missing topic."""


class ConfigError(IvslamError):
    """A configuration file or option is invalid."""


class InconsistentData(IvslamError):
    """The data contradict the model (an empty set) and the policy says stop."""

    exit_code = 3
