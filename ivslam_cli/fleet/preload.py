"""Imported once by the process pool's fork server, so that every worker forked from it
starts with ivslam's readers, writer and pipelines already imported (their jitted kernels
are then loaded from the on-disk cache by the first job of each worker)."""

from __future__ import annotations

import importlib

from ivslam_cli.fleet import audit, job  # noqa: F401
from ivslam_cli.slam import PIPELINES

for _module in ("ivslam_cli.logs", "ivslam_cli.logs.detect", "ivslam_cli.results.hdf5", "ivslam_cli.report.core",
                "ivslam_cli.config", *PIPELINES.values()):
    importlib.import_module(_module)
