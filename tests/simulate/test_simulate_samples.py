"""The committed sample logs are what their recorded commands produce."""

from __future__ import annotations

import shlex

import numpy as np
import pytest

from ivslam_cli.logs.ivslam_h5 import read_ivslam_h5
from tests.helpers.paths import SAMPLE_LOGS
from tests.helpers.ros_messages import decode


def _commands() -> dict[str, list[str]]:
    text = (SAMPLE_LOGS / "make_samples.sh").read_text().replace("\\\n", " ")
    out = {}
    for line in text.splitlines():
        if line.startswith('"$IVSLAM" simulate'):
            args = shlex.split(line)[2:]
            out[args[args.index("-o") + 1]] = args
    return out


def test_every_sample_is_recorded_and_small():
    cmds = _commands()
    logs = sorted(p.name for p in SAMPLE_LOGS.iterdir() if p.suffix in {".mcap", ".bag", ".h5"})
    assert logs and sorted(cmds) == logs
    for name in logs:
        assert (SAMPLE_LOGS / name).stat().st_size < 400_000, name


def test_h5_sample_matches_its_command(cli_run, tmp_path):
    cmds = _commands()
    name = next(n for n in cmds if n.endswith(".h5"))
    args = cmds[name]
    args[args.index("-o") + 1] = str(tmp_path / name)
    assert cli_run("simulate", *args).exit_code == 0
    a, b = read_ivslam_h5(SAMPLE_LOGS / name), read_ivslam_h5(tmp_path / name)
    assert np.array_equal(a.scans.ranges, b.scans.ranges) and np.array_equal(a.truth.pose, b.truth.pose)
    assert a.meta == b.meta


@pytest.mark.parametrize("name,fmt", [("pairs.mcap", "mcap"), ("landmarks.bag", "ros1")])
def test_ros_samples_decode_with_truth(name, fmt):
    d = decode(SAMPLE_LOGS / name, fmt)
    assert d["meta"].meta["scenario"] in name and d["truth"] and d["obs"]
