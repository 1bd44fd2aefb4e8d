"""``acv train``: (being written)."""
