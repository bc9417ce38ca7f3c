"""Build a result's provenance from what the reader said and what the run used."""

from __future__ import annotations

import shlex
import sys
from collections.abc import Mapping, Sequence
from typing import Any

from ivslam_cli import __version__
from ivslam_cli.logs.model import Provenance
from ivslam_cli.results.checksum import input_sha256
from ivslam_cli.results.model import ResultProvenance


def command_line(argv: Sequence[str] | None = None) -> str:
    """The command as a shell-quoted line (``ivslam`` + arguments; default ``sys.argv``)."""
    args = list(sys.argv[1:] if argv is None else argv)
    return shlex.join(["ivslam", *args])


def make_provenance(
    log: Provenance, config: Mapping[str, Any], argv: Sequence[str] | None = None
) -> ResultProvenance:
    """Provenance of a run over ``log`` with the resolved ``config`` (``Config.as_dict()``).

    The checksum is computed here, from the file or directory at ``log.path``.
    """
    return ResultProvenance(
        ivslam_version=__version__,
        command=command_line(argv),
        config={s: dict(v) for s, v in config.items()},
        input_path=str(log.path),
        input_sha256=input_sha256(log.path),
        input_format=log.format,
        topics=dict(log.topics),
        dropped=list(log.dropped),
        notes=list(log.notes),
    )
