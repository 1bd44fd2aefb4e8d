"""``acv validate``: the verdict checked on agents whose answer is known (issue 27,
docs/validation.md). :mod:`.design` fixes the arms and seeds, :mod:`.criteria` and
:mod:`.power` are the pre-registered analysis (numpy and scipy only), :mod:`.runs` trains
and measures the agents."""
