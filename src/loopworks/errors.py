"""Errors a user can act on. The CLI prints them as one line and exits with code 2."""

from __future__ import annotations


class LoopworksError(Exception):
    """Base of every error loopworks raises for bad user input."""


class ParameterError(LoopworksError, ValueError):
    """A block parameter is unknown, of the wrong type or out of its allowed range."""


class UnknownKindError(LoopworksError, KeyError):
    """A block kind that the registry does not know."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class InputError(LoopworksError, ValueError):
    """A bad runtime input: a non-positive dt, an unknown port, a malformed value."""


class FileFormatError(LoopworksError, ValueError):
    """A malformed input file (CSV, TOML): the message names the file, line or column."""
