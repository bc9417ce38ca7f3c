"""Parameters of the pairs pipeline, read once from the resolved configuration."""

from __future__ import annotations

from dataclasses import dataclass

from ivslam_cli.errors import ConfigError

HEADING_SOURCES = ("option", "odometry")


@dataclass(frozen=True)
class Params:
    """``[bounds]`` range/bearing bounds, ``[robust]`` q_pair/strict and ``[pairs]`` (see the
    configuration table for each key's meaning and default)."""

    range_abs: float
    range_rel: float
    bearing: float
    q: int
    strict: bool
    heading: tuple[float, float]
    heading_given: bool  # pairs.heading was set (else a heading bound the log states is used)
    heading_source: str
    eps: float
    anchor_id: int | None
    anchor_xy: tuple[float, float]
    reference_id: int | None
    max_pairs: int
    max_boxes: int
    max_work: int

    @classmethod
    def from_config(cls, cfg) -> Params:
        source = cfg["pairs.heading_source"]
        if source not in HEADING_SOURCES:
            raise ConfigError(f"[pairs] heading_source must be 'option' or 'odometry', got {source!r}")
        return cls(
            range_abs=float(cfg["bounds.range_abs"]), range_rel=float(cfg["bounds.range_rel"]),
            bearing=float(cfg["bounds.bearing"]), q=int(cfg["robust.q_pair"]), strict=bool(cfg["robust.strict"]),
            heading=tuple(float(v) for v in cfg["pairs.heading"]),
            heading_given=cfg.sources.get("pairs.heading", "default") != "default",
            heading_source=source, eps=float(cfg["pairs.eps"]), anchor_id=cfg["pairs.anchor_id"],
            anchor_xy=tuple(float(v) for v in cfg["pairs.anchor_xy"]), reference_id=cfg["pairs.reference_id"],
            max_pairs=int(cfg["pairs.max_pairs"]), max_boxes=int(cfg["pairs.max_boxes"]),
            max_work=int(cfg["pairs.max_work"]),
        )
