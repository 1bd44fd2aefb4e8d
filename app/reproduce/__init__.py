"""``acv reproduce``: the paper's experiments and their report."""
