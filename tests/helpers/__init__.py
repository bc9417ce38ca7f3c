"""What the tests share (see each module).

- ``hyp``: the Hypothesis profiles (``IVSLAM_HYPOTHESIS=dev|ci|soak``), ``examples(ci=N)`` and
  ``seeds(ci=N)``, which scale a test's own count with the profile.
"""
