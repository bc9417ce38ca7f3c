"""ivslam: guaranteed (interval, set-membership) SLAM over recorded robot logs.

Data flows one way: ``logs`` (readers) -> ``slam`` (pipelines built on ``interval``,
``contractors`` and ``paving`` kernels) -> ``results`` (HDF5) -> ``report``.
Importing this package is cheap: no numba kernel is compiled or loaded here.
"""

__version__ = "0.1.0"
