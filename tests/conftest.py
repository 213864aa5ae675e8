"""Test settings shared by every test module.

Property-based tests (hypothesis) draw parameters over decades; they run
without a deadline (symbolic work varies in time, and tests assert nothing
about wall time) and, under CI, derandomized so a run can be repeated.
"""

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "default",
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.differing_executors],
)
settings.register_profile("ci", parent=settings.get_profile("default"), derandomize=True, print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "default")
