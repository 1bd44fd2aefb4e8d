"""Errors that mean "the caller's input was wrong" (as opposed to a bug)."""


class InputError(ValueError):
    """Bad user input: an unknown env, a malformed tree file, an out-of-range parameter.

    Front ends turn it into a clear message (CLI: exit code 2; HTTP: a 4xx response).
    """


#: Seeds numpy, torch and Gymnasium all accept: ``np.random.default_rng`` rejects negative
#: seeds and ``torch.manual_seed`` seeds above ``2**64 - 1``.
SEED_LIMIT = 2**64


def seed_error(seed: int) -> str | None:
    """Why ``seed`` cannot be used, or None."""
    return None if 0 <= seed < SEED_LIMIT else f"seed must be in 0 .. 2**64-1, got {seed}"


def check_seed(seed: int) -> int:
    """Return ``seed`` if numpy, torch and Gymnasium all accept it; else :class:`InputError`."""
    if (message := seed_error(seed)) is not None:
        raise InputError(message)
    return seed
