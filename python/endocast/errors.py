"""The exceptions endocast raises (each message is the command line's)."""


class Error(Exception):
    """Any error of endocast."""


class InputError(Error, OSError):
    """An input that cannot be read: unreadable, truncated or malformed (CLI exit 3)."""


class ParameterError(Error, ValueError):
    """A value out of range or inconsistent with the input (CLI exit 4)."""


class NoResultError(Error):
    """A valid input without a result: no cavity enclosed by bone, all bone (CLI exit 5)."""


class OutOfMemoryError(Error, MemoryError):
    """The work does not fit in the memory allowed (CLI exit 6)."""
