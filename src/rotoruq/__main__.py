"""``python -m rotoruq``: the ``rotoruq`` command (:func:`rotoruq.study.cli.main`), as light
as the console script: a ``driver`` call answered by the driver server imports nothing more."""

import sys

from .study.cli import main

if __name__ == "__main__":
    sys.exit(main())
