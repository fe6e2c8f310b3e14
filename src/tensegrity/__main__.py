"""``python -m tensegrity``: the ``tensegrity`` command (as ``python -m tensegrity.cli``)."""

import sys

from tensegrity.cli.main import main

sys.exit(main())
