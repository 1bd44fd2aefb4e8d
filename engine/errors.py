"""Errors that mean "the caller's input was wrong" (as opposed to a bug)."""


class InputError(ValueError):
    """Bad user input: an unknown env, a malformed tree file, an out-of-range parameter.

    Front ends turn it into a clear message (CLI: exit code 2; HTTP: a 4xx response).
    """
