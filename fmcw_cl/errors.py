"""The project's own errors: each one is shown to the user as one clear line."""

from __future__ import annotations


class FmcwError(Exception):
    """An error the user can act on; printed as one line without a traceback."""


class CaptureError(FmcwError):
    """A capture file that cannot be read or does not follow the contract.

    The message always starts with the file name.
    """

    def __init__(self, path: object, problem: str) -> None:
        super().__init__(f"{path}: {problem}")
        self.path = path
        self.problem = problem
