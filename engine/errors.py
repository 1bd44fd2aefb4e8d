"""Errors that mean "the caller's input was wrong" (as opposed to a bug)."""


class InputError(ValueError):
    """Bad user input: an unknown env, a malformed tree file, an out-of-range parameter.

    Front ends turn it into a clear message (CLI: exit code 2; HTTP: a 4xx response).
    """


def check_seed(seed: int) -> int:
    """Return ``seed`` if numpy, torch and Gymnasium all accept it; else :class:`InputError`.

    ``np.random.default_rng`` rejects negative seeds and ``torch.manual_seed`` seeds above
    ``2**64 - 1``.
    """
    if not 0 <= seed < 2**64:
        raise InputError(f"seed must be in 0 .. 2**64-1, got {seed}")
    return seed
