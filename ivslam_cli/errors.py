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
        self.message = message
        super().__init__(f"{self.path}: {message}" if self.path else message)

    def about(self, path: str | Path) -> IvslamError:
        """This error said of ``path`` (unchanged if it already names a file)."""
        if self.path is not None:
            return self
        new = type(self).__new__(type(self))
        IvslamError.__init__(new, self.message, path)
        new.exit_code = self.exit_code
        return new


class LogError(IvslamError):
    """A log cannot be read: corrupt, truncated, empty, unknown format, missing topic."""


class ConfigError(IvslamError):
    """A configuration file or option is invalid."""


class OutputError(IvslamError):
    """An output cannot be written: the disk is full, a device error (an I/O failure, exit 1)."""

    exit_code = 1


class InconsistentData(IvslamError):
    """The data contradict the model (an empty set) and the policy says stop."""

    exit_code = 3
