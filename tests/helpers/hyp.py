"""Hypothesis profiles, and test counts that scale with them.

``IVSLAM_HYPOTHESIS`` selects the profile (tests/conftest.py loads it; ``--hypothesis-profile``
given on the command line wins):

- ``ci`` (the default, what ``make test`` and CI run): 100 examples per test unless the test
  asks for its own count; every count written in the tests is the ``ci`` count;
- ``dev`` (``make test-fast``): a fifth of every count (at least one), for the edit-test loop;
- ``soak``: ten times every count, for a developer looking for trouble (long).

No deadline in any profile (numba compiles on a test's first example, and a shared 2-core
machine makes timings meaningless) and no ``too_slow`` health check for the same reason.
Examples are random (not derandomized): nothing in the suite depends on which examples run,
and a failure is replayed from the local database (``.hypothesis/``) or from the printed blob.

A test that needs another count than the profile's default says how many it runs under ``ci``:
``@settings(max_examples=examples(ci=1500))``. Tests whose only random input is a numpy seed
take explicit seeds instead, so that a failure names its seed:
``@pytest.mark.parametrize("seed", seeds(ci=40))`` (seeds 0..39 under ``ci``, 0..7 under
``dev``, 0..399 under ``soak``).
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

ENV = "IVSLAM_HYPOTHESIS"
DEFAULT_PROFILE = "ci"
CI_EXAMPLES = 100  # the ci profile's max_examples: the unit of every count in the tests
PROFILES = {"dev": 20, "ci": CI_EXAMPLES, "soak": 10 * CI_EXAMPLES}

for _name, _n in PROFILES.items():
    settings.register_profile(_name, max_examples=_n, deadline=None, print_blob=True,
                              suppress_health_check=[HealthCheck.too_slow])


def load_profile(name: str | None = None) -> str:
    """Load ``name`` (default: ``$IVSLAM_HYPOTHESIS`` or ``ci``); returns the name loaded."""
    name = name or os.environ.get(ENV) or DEFAULT_PROFILE
    if name not in PROFILES:
        raise pytest.UsageError(f"{ENV}={name!r}: not a profile; have {', '.join(PROFILES)}")
    settings.load_profile(name)
    return name


def scale() -> float:
    """The loaded profile's max_examples over ci's (dev 0.2, ci 1, soak 10)."""
    return settings.default.max_examples / CI_EXAMPLES


def examples(*, ci: int, dev: int | None = None) -> int:
    """How many examples a test that runs ``ci`` of them under ``ci`` runs under the loaded
    profile (at least one); ``dev``, if given, is the count under ``dev`` (for tests whose
    every example is a whole run). Evaluated when the test module is imported, after conftest
    has loaded the profile."""
    if dev is not None and settings.get_current_profile_name() == "dev":
        return max(1, dev)
    return max(1, round(ci * scale()))


def seeds(*, ci: int, dev: int | None = None) -> list:
    """Seeds ``0 .. examples(ci=ci, dev=dev) - 1`` as parametrize values with ids ``seed<k>``:
    the ``dev`` seeds are the first of ``ci``'s, which are the first of ``soak``'s."""
    return [pytest.param(k, id=f"seed{k}") for k in range(examples(ci=ci, dev=dev))]


def lanes(values, *, fast) -> list:
    """``values`` as parametrize values, those not in ``fast`` marked ``slow``: every value runs
    in ``make test``, the ``fast`` ones in ``make test-fast`` too."""
    fast = list(fast)
    return [v if v in fast else pytest.param(*(v if isinstance(v, tuple) else (v,)), marks=pytest.mark.slow)
            for v in values]
