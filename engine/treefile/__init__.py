"""The ``acv.tree/1`` document: one labelled bracket and its Preference Tree.

The same JSON is the CLI's file format and the REST API's body (README "Tree file format").
The matches are the source of truth: loading rebuilds the tree from them and rejects a file
whose stored tree disagrees, so a hand-edited or truncated file cannot pass as valid.

A match the judge could not tell carries ``"tie": true`` (its ``winner`` is the seeded coin's);
the key is absent on every other match, so documents without ties are unchanged
(docs/method.md §2.14).

:mod:`~engine.treefile.document` holds the document (and replays its bracket with another
judge), :mod:`~engine.treefile.write` its JSON, :mod:`~engine.treefile.read` the validating
reader.
"""

from engine.treefile.document import SCHEMA, TreeDocument, make_document, replay
from engine.treefile.read import load_tree, tree_from_json
from engine.treefile.write import dump_tree, dumps, tree_to_json

__all__ = [
    "SCHEMA",
    "TreeDocument",
    "dump_tree",
    "dumps",
    "load_tree",
    "make_document",
    "replay",
    "tree_from_json",
    "tree_to_json",
]
