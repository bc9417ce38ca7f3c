"""Intel Research Lab end to end: `ivslam run intel_gfs.json.xz --mode lidar` with
configs/intel_lab.toml (raw odometry at 910 keyframes, 180-beam scans), then `ivslam report
--relations intel.relations.xz`: every benchmark relation with both ends on keyframes must hold
its true relative pose within what the two pose boxes allow.

The run turns pose contraction off (``lidar.contract = false``, appended to the checked-in
config): with these odometry bounds the boxes are ~0.9 m and 0.75 rad wide after one keyframe
step, contraction changes no box of this log (checked when the config was written: identical
boxes with and without it) and costs minutes; the rest of the config is used as it is."""

from __future__ import annotations

import json
import lzma

import numpy as np
import pytest

from tests.helpers.paths import CONFIGS

pytestmark = pytest.mark.datasets


def _keyframe_stamps(path) -> np.ndarray:
    return np.array(sorted(float(k) for k in json.loads(lzma.open(path).read())["map"]))


@pytest.mark.slow  # ~30 s: the keyframe run over the whole Intel log
def test_intel_relations_end_to_end(datasets, cli_run, tmp_path):
    log = datasets / "intel_lab" / "intel_gfs.json.xz"
    relations = datasets / "intel_lab" / "intel.relations.xz"
    cfg = tmp_path / "intel_lab.toml"
    text = (CONFIGS / "intel_lab.toml").read_text()
    assert "\n[lidar]\n" in text and "contract" not in text.split("\n[lidar]\n", 1)[1]
    cfg.write_text(text.rstrip("\n") + "\ncontract = false\n")
    out = tmp_path / "intel.h5"
    res = cli_run("run", log, "--mode", "lidar", "--config", cfg, "-o", out)
    assert res.exit_code == 0, res.output
    res = cli_run("report", out, "--relations", relations, "--json")
    assert res.exit_code == 0, res.output
    rel = json.loads(res.output)["relations"]

    # independently: relations whose two stamps are keyframe stamps (to the microsecond the
    # files are printed with); the run uses every keyframe (the odometry is at the keyframes)
    kf = _keyframe_stamps(log)
    r = np.loadtxt(lzma.open(relations))
    on = [np.min(np.abs(r[:, c, None] - kf[None]), axis=1) <= 1e-6 for c in (0, 1)]
    both = int(np.count_nonzero(on[0] & on[1]))
    assert both == 90  # the datasets README's figure, recomputed here
    assert rel["relations"] == r.shape[0] == 2984
    assert rel["matched"] == both and rel["ambiguous"] == 0 and rel["same_pose"] == 0
    assert rel["one_end_matched"] == int(np.count_nonzero(on[0] ^ on[1]))
    # the guarantee: every true relative pose within the two boxes' relative enclosure
    assert rel["inside"] == rel["matched"] and rel["sound"] and not rel["failures"]
    assert all(e["inside"] for e in rel["list"])
    w = rel["width"]
    assert all(w[k]["median"] > 0 for k in ("x", "y", "theta"))

    # and as text, for the record
    res = cli_run("report", out, "--relations", relations)
    assert res.exit_code == 0 and f"inside:   {both}/{both} true relative poses" in res.output


@pytest.mark.slow  # the submap run over the whole Intel log
def test_intel_relations_with_submaps(datasets, cli_run, tmp_path):
    """The same log with its own config (scan-to-submap matching on): the result holds every
    scan's box in its submap's frame (``/relative``: anchor → scan), and ``report --relations``
    meets what the two global boxes allow with them (directly, inverted or chained): every
    relation inside, those that used them far tighter than the global boxes alone."""
    log = datasets / "intel_lab" / "intel_gfs.json.xz"
    relations = datasets / "intel_lab" / "intel.relations.xz"
    out = tmp_path / "intel.h5"
    res = cli_run("run", log, "--mode", "lidar", "--config", CONFIGS / "intel_lab.toml", "-o", out)
    assert res.exit_code == 0, res.output
    res = cli_run("report", out, "--relations", relations, "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.output)
    rel = doc["relations"]
    kf = _keyframe_stamps(log)
    assert doc["submaps"]["count"] >= 1 and doc["relative"]["count"] >= kf.size - doc["submaps"]["count"]
    r = np.loadtxt(lzma.open(relations))
    on = [np.min(np.abs(r[:, c, None] - kf[None]), axis=1) <= 1e-6 for c in (0, 1)]
    both = int(np.count_nonzero(on[0] & on[1]))
    assert both == 90 and rel["matched"] == both
    assert rel["inside"] == both and rel["sound"] and not rel["failures"]
    assert all((e["source"] != "global") == (e["hops"] > 0) for e in rel["list"])
    assert rel["used_relative"] > 0
    for name, v in rel["by_source"].items():
        if name != "global" and v["count"]:
            w, wg = v["width"], v["global_boxes_width"]
            for k in ("x", "y", "theta"):
                assert 0 < w[k]["median"] < wg[k]["median"]
    # the 68 relations between consecutive keyframes, met with the scan pairs (lidar.pair_boxes:
    # each keyframe matched against the one before it alone; x / y / θ medians 0.2672 / 0.3439 m /
    # 0.1266 rad over the 69 direct ones; 0.855 / 0.855 / 0.705 without)
    consecutive = [e for e in rel["list"] if abs(e["pose2"] - e["pose1"]) == 1]
    assert len(consecutive) == 68 and all(e["source"] == "relative" and e["inside"] for e in consecutive)
    w = rel["by_source"]["relative"]["width"]
    assert w["x"]["median"] < 0.28 and w["y"]["median"] < 0.36 and w["theta"]["median"] < 0.13, w
    # the pairs also seed the tracking (each keyframe's prior in a submap holding the one before
    # it met with that one's box ⊕ the pair): relative boxes 0.605 m / 0.189 rad (1.06 / 0.601
    # without), 35 loop constraints (16)
    fw = doc["final_width"]
    assert fw["pose_relative"]["median"] < 0.7 and fw["pose_relative_heading"]["median"] < 0.25, fw
    assert doc["loops"]["found"] >= 25, doc["loops"]["found"]
    print("\nIntel submaps: " + "; ".join(
        f"{name} {v['count']}: x {v['width']['x']['median']:.3g}, y {v['width']['y']['median']:.3g} m, "
        f"θ {v['width']['theta']['median']:.3g} rad" for name, v in rel["by_source"].items() if v["count"]))
