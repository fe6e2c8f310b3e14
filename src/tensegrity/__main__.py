"""``python -m tensegrity``: the ``tensegrity`` command (as ``python -m tensegrity.cli``)."""

import sys

from tensegrity.cli.main import main

if __name__ == "__main__":  # (importing it, as a documentation tool does, runs nothing)
    sys.exit(main())
