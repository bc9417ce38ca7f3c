"""A small hand-made :class:`Result` with known truth (tests, docs, trying ``ivslam report``).

Every enclosure contains the truth by construction, with a known margin; the tests break
one on purpose to check that the report catches it. Not produced by any pipeline.
"""

from __future__ import annotations

import numpy as np

from ivslam_cli import __version__
from ivslam_cli.logs.model import Dropped, GroundTruth
from ivslam_cli.results.model import (
    CELL_EMPTY,
    CELL_OBSTACLE,
    LABEL_BOUNDARY,
    LABEL_INNER,
    Consistency,
    EmptyEvents,
    Landmarks,
    MapGrid,
    PairSubpavings,
    Poses,
    Rejections,
    Result,
    ResultProvenance,
    WidthHistory,
)

TRUE_LANDMARKS = {1: (2.0, 1.0), 2: (-1.0, 3.0), 3: (4.0, -2.0)}


def _centred(xy: np.ndarray, half: float) -> np.ndarray:
    """Boxes ``[..., d, 2]`` centred on ``xy[..., d]`` with half-width ``half``."""
    xy = np.asarray(xy, dtype=np.float64)
    return np.stack([xy - half, xy + half], axis=-1)


def example_result(mode: str = "pairs", *, n_poses: int = 6, with_grid: bool = True) -> Result:
    """A consistent synthetic result: 3 landmarks, 3 pairs, a short pose track, a 4×5 grid."""
    ids = np.array(sorted(TRUE_LANDMARKS), dtype=np.int64)
    truth_xy = np.array([TRUE_LANDMARKS[i] for i in ids])

    # Landmark boxes: centred 0.05 off the truth, half-width 0.2 (margin 0.15).
    lm_box = _centred(truth_xy + 0.05, 0.2)

    # Pair (i, j) subpavings around dl = m_i − m_j: a 2×2 block of 0.1-boxes whose
    # common corner is 0.03 off the truth, the first one inner, the rest boundary.
    pi, pj, boxes, labels, offsets = [], [], [], [], [0]
    for a in range(len(ids)):
        for b in range(a + 1, len(ids)):
            dl = truth_xy[a] - truth_xy[b] + 0.03
            for k, (sx, sy) in enumerate(((0, 0), (-1, 0), (0, -1), (-1, -1))):
                lo = dl + 0.1 * np.array([sx, sy])
                boxes.append(np.stack([lo, lo + 0.1], axis=-1))
                labels.append(LABEL_INNER if k == 0 else LABEL_BOUNDARY)
            pi.append(ids[a])
            pj.append(ids[b])
            offsets.append(len(boxes))
    pairs = PairSubpavings(
        i=np.array(pi, dtype=np.int64),
        j=np.array(pj, dtype=np.int64),
        offsets=np.array(offsets, dtype=np.int64),
        boxes=np.array(boxes, dtype=np.float64),
        label=np.array(labels, dtype=np.uint8),
    )

    # Poses: a straight line at 1 m/s along x, heading 0.1 rad, box stamps every 1 s;
    # truth sampled every 0.5 s (so half the truth stamps fall between two boxes).
    stamp = np.arange(n_poses, dtype=np.float64)
    centre = np.stack([stamp, 0.5 * np.ones(n_poses), 0.1 * np.ones(n_poses)], axis=1)
    pose_box = _centred(centre, 0.3)
    g_stamp = np.arange(0.0, n_poses - 1 + 1e-9, 0.5)
    g_pose = np.stack([g_stamp, 0.5 * np.ones_like(g_stamp), 0.1 * np.ones_like(g_stamp)], axis=1)

    # Width histories: every entity shrinking over 4 steps.
    steps = np.arange(4, dtype=np.int64)
    def hist(entities: np.ndarray, start: float, definition: str) -> WidthHistory:
        ent = np.repeat(entities, len(steps), axis=0)
        st = np.tile(steps, len(entities))
        w = start / (1.0 + st.astype(np.float64))
        return WidthHistory(entity=ent, step=st, stamp=st.astype(np.float64) * 0.5, width=w, definition=definition)

    pair_ent = np.stack([pairs.i, pairs.j], axis=1)
    lm_ent = np.stack([ids, -np.ones_like(ids)], axis=1)
    pose_ent = np.stack([np.arange(n_poses, dtype=np.int64), -np.ones(n_poses, np.int64)], axis=1)
    widths = {
        "pair": hist(pair_ent, 0.8, "largest side of the hull of the outer approximation [m]"),
        "landmark": hist(lm_ent, 1.6, "largest side of the box in x, y [m]"),
        "pose": hist(pose_ent, 2.4, "largest side of the box in x, y [m]"),
    }

    events = EmptyEvents(
        stamp=np.array([1.5]),
        step=np.array([3], dtype=np.int64),
        constraint=np.array(["pair_intersection"]),
        entity=np.array([[1, 3]], dtype=np.int64),
        measurement=np.array([7], dtype=np.int64),
        text=np.array(["S(1,3) at step 3 misses all earlier sets; relaxed (q=1)"]),
    )
    rejected = Rejections(
        stream=np.array(["observations", "observations"]),
        index=np.array([7, 12], dtype=np.int64),
        reason=np.array(["q-relaxed: inconsistent with pair (1,3)", "range beyond max"]),
    )
    truth = GroundTruth(
        pose_stamp=g_stamp,
        pose=g_pose,
        landmark_id=ids.copy(),
        landmark_xy=truth_xy.copy(),
        outliers={"observations": np.zeros(20, dtype=bool)},
    )
    grid = None
    if with_grid:
        state = np.zeros((4, 5), dtype=np.uint8)
        state[1:3, 1:4] = CELL_EMPTY
        state[3, :] = CELL_OBSTACLE
        grid = MapGrid(origin=np.array([-1.0, -0.5]), resolution=0.25, state=state)
    config = {
        "bounds": {"range_abs": 0.1, "range_rel": 0.0, "bearing": 0.0175},
        "robust": {"q_pair": 1, "strict": False},
        "pairs": {"eps": 0.05, "heading": [0.0, 0.0]},
    }
    return Result(
        mode=mode,
        provenance=ResultProvenance(
            ivslam_version=__version__,
            command="ivslam run sim.mcap --mode pairs -o out.h5",
            config=config,
            input_path="/data/sim.mcap",
            input_sha256="0" * 64,
            input_format="mcap",
            topics={"observations": "/landmarks"},
            dropped=[Dropped("observations", 2, "unknown landmark id")],
            notes=["synthetic example"],
        ),
        runtime_s=0.25,
        poses=Poses(stamp=stamp, box=pose_box),
        landmarks=Landmarks(id=ids, box=lm_box),
        pairs=pairs,
        grid=grid,
        consistency=Consistency(
            empty_events=events,
            q={"pair": 1},
            rejected=rejected,
            widths=widths,
            assumption="bounds hold for all but at most q=1 observations per pair",
        ),
        truth=truth,
        stats={"pair_observations": 42, "note": "example"},
    )
