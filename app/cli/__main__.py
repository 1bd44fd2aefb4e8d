"""``python -m app.cli``: the same as the ``acv`` console script."""

from app.cli import main

main()
