"""Shared test configuration: Hypothesis profiles (tests/test_fuzz.py).

``ci`` (the default) is reproducible: examples derived from each test's name (``derandomize``),
no example database on disk, no deadline (a shared CI machine's timing is not a property).
``HYPOTHESIS_PROFILE=explore pytest tests/test_fuzz.py`` draws fresh random examples, ten times
as many, to hunt for new failures; a failure it finds is kept as an ``@example`` of its test.
"""

from __future__ import annotations

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None, deadline=None, print_blob=True)
settings.register_profile("explore", database=None, deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
