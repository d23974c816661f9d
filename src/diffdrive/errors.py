"""The error every file reader and writer raises: ``TableError``, a ``ValueError`` whose
message names the file, and the line and column when known."""

__all__ = ["TableError"]


class TableError(ValueError):
    """A bad input file; the message names the file, and the line and column when known."""
