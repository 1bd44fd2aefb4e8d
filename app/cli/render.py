"""``acv render``: (being written)."""
