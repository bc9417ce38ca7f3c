"""`ivslam inspect` on every dataset, text and --json, and its error exits."""

from __future__ import annotations

import json

import pytest

CASES = [
    ("ros2_turtlebot4_comprobo22/macfirst_floor_take_2", [], {"lidar"}, 357),
    ("mcap_turtlebot4_comprobo22/macfirst_floor_take_2.mcap", [], {"lidar"}, 357),
    ("ros1_neato_ksoltan/left_side.bag", [], {"lidar"}, 174),
    ("ros1_ccny_urg04lx_scan_only/demo.bag", [], {"lidar"}, 360),
    ("intel_lab/intel.gfs.log.xz", [], {"lidar"}, 910),
    ("carmen_corrected/aces-corrected.log.gz", [], {"lidar"}, 440),
    ("breezyslam_mines/exp1.dat.xz", [], {"lidar"}, 756),
    ("victoria_park/victoria_park.txt.xz", [], {"pairs", "landmarks"}, 3640),
    ("mrclam/MRCLAM_Dataset6", ["--robot", "2"], {"pairs", "landmarks"}, None),
]


@pytest.mark.datasets
@pytest.mark.parametrize("rel,extra,modes,count", CASES, ids=[c[0].split("/")[0] for c in CASES])
def test_inspect_json_and_text(datasets, cli_run, rel, extra, modes, count):
    res = cli_run("inspect", datasets / rel, "--json", *extra)
    assert res.exit_code == 0, res.output
    s = json.loads(res.output)
    assert {m for m, ok in s["modes"].items() if ok} == modes
    streams = {x["stream"]: x for x in s["streams"]}
    main = streams.get("scans") or streams["observations"]
    if count is not None:
        assert main["count"] == count
    assert main["duration_s"] > 0
    text = cli_run("inspect", datasets / rel, *extra)
    assert text.exit_code == 0
    assert f"{main['count']:>8d}" in text.output
    assert "run modes: " + ", ".join(m for m in ("pairs", "landmarks", "lidar") if m in modes) \
        in text.output


@pytest.mark.datasets
def test_inspect_reports_topics_truth_and_lidar_input(datasets, cli_run):
    s = json.loads(cli_run("inspect", datasets / "ros1_ccny_urg04lx_scan_only/demo.bag",
                           "--json").output)
    assert s["topics"]["/scan"] == {"type": "sensor_msgs/msg/LaserScan", "count": 360}
    assert s["lidar_input"].startswith("scans only")
    assert s["ground_truth"] == {"poses": 0, "landmarks": 0}
    m = json.loads(cli_run("inspect", datasets / "mrclam/MRCLAM_Dataset6", "--json").output)
    assert m["ground_truth"]["landmarks"] == 15 and m["ground_truth"]["poses"] > 0
    assert any("other robots" in d["reason"] for d in m["dropped"])
    n = json.loads(cli_run("inspect", datasets / "ros1_neato_ksoltan/left_side.bag",
                           "--json").output)
    scans = next(x for x in n["streams"] if x["stream"] == "scans")
    assert scans["beams_min"] == scans["beams_max"] == 360
    assert scans["rate_hz"] == pytest.approx(5.0, abs=0.1)


@pytest.mark.datasets
def test_inspect_says_when_scan_stamps_jitter_off_a_clock_and_scans_repeat(datasets, cli_run):
    """exp1's logger stamps each scan when it reads it: the stamps jitter off the sensor's clock
    and four reads repeat the previous scan (lidar.scan_clock); ACES's keyframes have no clock."""
    s = json.loads(cli_run("inspect", datasets / "breezyslam_mines/exp1.dat.xz", "--json").output)
    scans = {x["stream"]: x for x in s["streams"]}["scans"]
    assert scans["repeated_scans"] == 4 and 0.0985 < scans["clock_period"] < 0.0989
    lo, hi = scans["stamps_off_clock"]
    assert lo < -0.03 and hi > 0.02
    text = cli_run("inspect", datasets / "breezyslam_mines/exp1.dat.xz").output
    assert "4 scan(s) repeat" in text and 'lidar.scan_clock = "fitted"' in text
    aces = json.loads(cli_run("inspect", datasets / "carmen_corrected/aces-corrected.log.gz", "--json").output)
    a = {x["stream"]: x for x in aces["streams"]}["scans"]
    assert a["repeated_scans"] == 0 and "clock_period" not in a


def test_inspect_help_has_example(cli_run):
    res = cli_run("inspect", "--help")
    assert res.exit_code == 0
    assert any(line.strip().startswith("ivslam inspect") for line in res.output.splitlines())


def test_inspect_errors_are_one_line(tmp_path):
    from click.testing import CliRunner

    from ivslam_cli.cli import cli

    bad = tmp_path / "bad.bag"
    bad.write_bytes(b"#ROSBAG V2.0\n\x05\x00")
    unknown = tmp_path / "a.xyz"
    unknown.write_text("nothing\n")
    for args in (["inspect", str(bad)], ["inspect", str(unknown)],
                 ["inspect", str(tmp_path / "missing.mcap")], ["inspect", str(tmp_path)],
                 ["inspect", str(unknown), "--format", "nope"]):
        res = CliRunner().invoke(cli, args)
        assert res.exit_code == 2, (args, res.output)
        assert "Traceback" not in res.output
        err = res.output.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("ivslam: error: "), res.output
