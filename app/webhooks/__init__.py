"""Webhooks (issue 29 §3): a researcher's URLs for a study's or a survey's events, the
transactional outbox every feature writes its events to (:mod:`app.webhooks.outbox`), their
signed delivery with retries (:mod:`app.webhooks.delivery`), each webhook in a lane of its
own (:mod:`app.webhooks.scheduler`), and the checks that keep them off private addresses
(:mod:`app.webhooks.targets`).

First in the chain of features: every other feature writes events to the outbox, in its own
transactions, so this package imports none of them.
"""
