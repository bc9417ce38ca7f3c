"""Where things live: the repository, its sample logs and configs, and the real datasets."""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SAMPLE_LOGS = REPO / "sample_logs"
CONFIGS = REPO / "configs"
# ``../shared/datasets`` next to the checkout unless IVSLAM_DATASETS says otherwise; tests reach it
# through the ``datasets`` fixture (tests/conftest.py), which skips when it is absent.
DATASETS = Path(os.environ.get("IVSLAM_DATASETS", REPO.parent / "shared" / "datasets")).resolve()
