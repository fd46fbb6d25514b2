"""Hypothesis profiles for the fuzz tests: a small budget in CI, a large one for the nightly run.

``MISSIONTREE_FUZZ=nightly`` (or ``HYPOTHESIS_PROFILE=nightly``) runs 10,000 fresh random cases per
test; the default ``ci`` profile runs a few hundred (a few seconds each), derandomized so that CI is a
reproducible gate (the same cases on every run: finding new ones is the nightly run's job). Every case
must end in a value or in missiontree's own ConfigError family (ProblemsError and its subclasses): any
other exception is a crash, and any case slower than the deadline a hang. A crash found here becomes a
plain test beside the code it broke.

    MISSIONTREE_FUZZ=nightly .venv/bin/pytest -q tests/fuzz -p no:cacheprovider
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

_COMMON = {
    "deadline": 5_000,  # ms per case: generous for a shared 2-core machine, still catches hangs
    "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large,
                              HealthCheck.function_scoped_fixture],
    "print_blob": True,
}
settings.register_profile("ci", max_examples=200, derandomize=True, **_COMMON)
settings.register_profile("nightly", max_examples=10_000, derandomize=False, **_COMMON)
settings.load_profile(os.environ.get("MISSIONTREE_FUZZ") or os.environ.get("HYPOTHESIS_PROFILE") or "ci")
