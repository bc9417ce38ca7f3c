"""One scan's q over all its submaps (:mod:`ivslam_cli.slam.lidar.submap_track`): a scan
q-relaxed in one submap is matched again with ``q_retry`` in the others, and the scans of the
next ``q_hold`` seconds are matched with ``q_retry`` from the start."""

from __future__ import annotations

import pytest

from ivslam_cli.config import resolve_config
from ivslam_cli.slam.lidar import Params as LidarParams
from ivslam_cli.slam.lidar.pipeline import run, usable_scans
from ivslam_cli.slam.lidar.submap_track import Track
from ivslam_cli.slam.lidar.submaps import track_submaps
from tests.helpers.lidar_submap import phantoms
from tests.helpers.lidar_truth import assert_contained, members_outside

Q = {"lidar.q_beams": 5, "lidar.q_retry": 30}


@pytest.mark.slow  # ~20 s
def test_the_scans_after_a_relaxed_one_are_held_and_keep_the_truth():
    """Scans 60–89 each have about 17 phantom returns (more than q_beams = 5): some of them still
    agree, with 5, with a wrong pose. Held for q_hold after each relaxed scan, every relative box
    in every submap keeps the truth; without the hold the truth is lost."""
    log, bad = phantoms(seed=5, first=60, last=90, steps=150)
    res = run(bad, LidarParams.from_config(resolve_config(None, Q, log_bounds=log.bounds)))
    assert res.stats["scans_q_relaxed"] > 0 and res.stats["scans_q_held"] > 0
    assert "q_hold = 1 s" in res.consistency.assumption
    assert members_outside(bad, res)[0] == 0
    assert_contained(res, ("pose", "pose_relative", "map_free"))
    off = run(bad, LidarParams.from_config(resolve_config(None, {**Q, "lidar.q_hold": 0.0}, log_bounds=log.bounds)))
    assert off.stats["scans_q_held"] == 0 and members_outside(bad, off)[0] > 0


@pytest.mark.slow  # ~10 s
def test_a_scan_relaxed_in_one_submap_is_matched_with_q_retry_in_all(monkeypatch):
    """Every scan has phantoms; wherever one was q-relaxed, its match in each of its other
    submaps was made with q_retry (again, if it had been made with q_beams) before anything was
    contracted or mapped."""
    log, bad = phantoms(seed=3, first=0, last=150, steps=150)
    p = LidarParams.from_config(resolve_config(None, {**Q, "lidar.q_hold": 0.0}, log_bounds=log.bounds))
    scans, _ = usable_scans(bad.scans, p.beams, p.max_range, p.eps, None)
    committed = []
    commit = Track.commit

    def spy(self, s, j, k, scan, rp, rt, out, relaxed):
        if out.matched:
            committed.append((j, s.index, out.q, out.q_relaxed))
        return commit(self, s, j, k, scan, rp, rt, out, relaxed)

    monkeypatch.setattr(Track, "commit", spy)
    t = track_submaps(bad, p, scans)
    relaxed_rows = {j for j, _ in t.q_relaxed}
    assert t.q_rematched and not set(t.q_rematched) & set(t.q_relaxed)
    of_relaxed = [c for c in committed if c[0] in relaxed_rows]
    assert len(of_relaxed) > len(t.q_relaxed)  # relaxed scans matched in more than one submap
    assert all(relaxed or q == p.q_retry for _, _, q, relaxed in of_relaxed)
    assert {(j, si) for j, si, _, relaxed in of_relaxed if relaxed} == set(t.q_relaxed)
