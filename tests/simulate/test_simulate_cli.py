"""`ivslam simulate` from the command line: outputs, determinism, one-line errors."""

from __future__ import annotations

import pytest

from ivslam_cli.logs.ivslam_h5 import read_ivslam_h5


def test_cli_writes_and_is_deterministic(cli_run, tmp_path):
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    for p in (a, b):
        res = cli_run("simulate", "--scenario", "landmarks", "--steps", "30", "--seed", "4", "-o", p)
        assert res.exit_code == 0, res.output
    la, lb = read_ivslam_h5(a), read_ivslam_h5(b)
    assert (la.observations.range == lb.observations.range).all()
    assert la.meta["config"]["seed"] == 4 and la.meta["scenario"] == "landmarks"


def test_cli_bound_options_reach_the_log(cli_run, tmp_path):
    out = tmp_path / "l.h5"
    res = cli_run("simulate", "--scenario", "lidar", "--sensor", "sick", "--steps", "5", "--range-abs", "0.02",
                  "--odom-w-rel", "0.1", "-o", out)
    assert res.exit_code == 0, res.output
    log = read_ivslam_h5(out)
    assert log.bounds["range_abs"] == 0.02 and log.bounds["odom_w_rel"] == 0.1
    assert log.scans.offsets[1] == 180


def test_cli_format_option_overrides_suffix(cli_run, tmp_path):
    out = tmp_path / "bagdir"
    res = cli_run("simulate", "--steps", "5", "--format", "ros2-mcap", "-o", out)
    assert res.exit_code == 0, res.output
    assert (out / "metadata.yaml").is_file() and list(out.glob("*.mcap"))


@pytest.mark.parametrize("args,needle", [
    (["--steps", "1"], "--steps"),
    (["--outlier-rate", "2"], "--outlier-rate"),
    (["--range-abs", "-1"], "range_abs"),
    (["--scenario", "pairs", "--odom-v", "0.1"], "does not apply"),
    (["--scenario", "lidar", "--world", "atlantis"], "unknown world"),
    (["--scenario", "warp"], "warp"),
    (["--noise", "gauss"], "gauss"),
    (["--steps", "10", "--duration", "3"], "not both"),
    (["--scenario", "lidar", "--beam-angle", "0.003"], "below half the beam step of urg-04lx"),
    (["--scenario", "lidar", "--beam-model", "fan"], "fan"),
])
def test_cli_bad_values_fail_on_one_line(cli_run, tmp_path, args, needle):
    out = tmp_path / "x.mcap"
    res = cli_run("simulate", *args, "-o", out)
    assert res.exit_code != 0
    assert needle in res.output and "Traceback" not in res.output
    errors = [l for l in res.output.splitlines() if "rror" in l]
    assert len(errors) == 1
    assert not out.exists()


def test_cli_refuses_to_overwrite(cli_run, tmp_path):
    out = tmp_path / "x.mcap"
    assert cli_run("simulate", "--steps", "5", "-o", out).exit_code == 0
    before = out.read_bytes()
    res = cli_run("simulate", "--steps", "5", "--seed", "2", "-o", out)
    assert res.exit_code != 0 and "use --force" in res.output and "Traceback" not in res.output
    assert out.read_bytes() == before
    assert cli_run("simulate", "--steps", "5", "--seed", "2", "-o", out, "--force").exit_code == 0
    assert out.read_bytes() != before


def test_cli_help_has_example(cli_run):
    res = cli_run("simulate", "--help")
    assert res.exit_code == 0 and "ivslam simulate --scenario" in res.output


def test_cli_beam_model_reaches_the_log_and_help_states_the_cones(cli_run, tmp_path):
    from ivslam_cli.simulate.sensors import PROFILES

    for model, h in (("cone", PROFILES["sick"].half_step()), ("ray", 0.0)):
        out = tmp_path / f"{model}.h5"
        res = cli_run("simulate", "--scenario", "lidar", "--sensor", "sick", "--steps", "5", "--beam-model", model,
                      "-o", out)
        assert res.exit_code == 0, res.output
        log = read_ivslam_h5(out)
        assert log.meta["beam_model"] == model and log.bounds["beam_angle"] == h
    text = " ".join(cli_run("simulate", "--help").output.split())
    for name, prof in PROFILES.items():
        assert f"{name} {prof.half_step():.7f}" in text
