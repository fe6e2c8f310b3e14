"""``python -m tensegrity.cli``: the ``tensegrity`` command."""

import sys

from tensegrity.cli.main import main

sys.exit(main())
