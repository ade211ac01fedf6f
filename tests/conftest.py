"""Test-suite settings: the Hypothesis profiles of the property tests.

``default`` keeps the normal suite fast; it draws new examples on every run, except under CI
(``CI`` set, as ``.ci/run`` does), where it is derandomised so the same commit always runs the
same examples and a landing cannot hinge on a lucky draw. ``slow`` (``HYPOTHESIS_PROFILE=slow``)
runs at least 10,000 examples per property per kind, for a one-off deep run."""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

settings.register_profile(
    "default", max_examples=int(os.environ.get("LOOPWORKS_EXAMPLES", "100")), deadline=None,
    derandomize=bool(os.environ.get("CI")), print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                           HealthCheck.data_too_large])
settings.register_profile(
    "slow", max_examples=10_000, deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                           HealthCheck.data_too_large])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


def pytest_xdist_auto_num_workers(config: object) -> int:
    """``-n auto`` (the default in pyproject.toml): one worker more than the machine has
    cores. A fifth of the suite's time is spent waiting on the wall clock (the live tests'
    scans and timeouts, fresh processes starting), during which a worker leaves its core
    idle; the extra worker fills it (2 cores: 150 s with two workers, 142 s with three)."""
    return (os.cpu_count() or 1) + 1
