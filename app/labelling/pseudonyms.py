"""The shared dataset's pseudonyms: keyed hashes of a study's ids, one home for every config
that names people or runs (:mod:`app.labelling.dataset`,
:mod:`app.labelling.dataset_evaluations`)."""

from __future__ import annotations

import hashlib
import hmac
from dataclasses import dataclass


@dataclass(frozen=True)
class Pseudonyms:
    """Keyed hashes of one study's ids: the same salt and id give the same pseudonym."""

    salt: bytes
    study_id: int

    def of(self, what: str, value: object) -> str:
        """The pseudonym of ``value``, an id of kind ``what`` (``participant``, ``external``,
        ``evaluator``, ``run``)."""
        message = f"acv-dataset/{self.study_id}/{what}/{value}".encode()
        return hmac.new(self.salt, message, hashlib.sha256).hexdigest()[:32]
