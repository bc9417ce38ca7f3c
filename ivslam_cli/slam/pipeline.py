"""What every pipeline shares: the empty-event record, the assembly of a :class:`Result`.

A pipeline is a subpackage of :mod:`ivslam_cli.slam` with the same small surface:

- ``Params``: frozen, typed parameters, built once from the resolved configuration by
  ``Params.from_config(cfg)`` (the only place a pipeline reads configuration keys);
- ``run(log, params, progress=None) -> Result``: the whole run over one log — enclosures,
  consistency record (empty events, rejections, width histories, the assumption under which
  the result is guaranteed), counters, and the pipeline's other products;
- ``summary(result) -> str``: the one line ``ivslam run`` prints.

The registry (:mod:`ivslam_cli.slam`) maps ``--mode`` to the pipeline and fills in what the
run cannot know (the resolved configuration and the command line of the provenance).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from ivslam_cli.logs.model import Dropped, LogData
from ivslam_cli.results.model import EmptyEvents, Result
from ivslam_cli.results.provenance import make_provenance

#: one empty event: (stamp, step, constraint family, entity (a, b), measurement index or -1, text)
EventRow = tuple[float, int, str, tuple[int, int], int, str]


def empty_events(rows: Iterable[EventRow]) -> EmptyEvents:
    """The consistency record's empty events from rows (kept in the order given)."""
    rows = list(rows)
    return EmptyEvents(
        stamp=np.array([r[0] for r in rows], float),
        step=np.array([r[1] for r in rows], np.int64),
        constraint=np.array([r[2] for r in rows], dtype=str).reshape(-1),
        entity=np.array([r[3] for r in rows], np.int64).reshape(-1, 2),
        measurement=np.array([r[4] for r in rows], np.int64),
        text=np.array([r[5] for r in rows], dtype=str).reshape(-1),
    )


def make_result(mode: str, log: LogData, *, dropped: Iterable[Dropped] = (), **parts) -> Result:
    """A :class:`Result` of ``mode`` over ``log``: provenance from the reader (the registry adds
    the configuration and command), the log's truth, the pipeline's ``parts`` (``consistency``,
    ``stats``, enclosures, ...) and the reader's plus the pipeline's dropped records."""
    prov = make_provenance(log.provenance, {}, ())
    prov.dropped = list(prov.dropped) + list(dropped)
    return Result(mode=mode, provenance=prov, runtime_s=0.0, truth=log.truth, **parts)
