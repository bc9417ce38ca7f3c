"""Configuration: defaults table, precedence, one-line errors, the markdown reference."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ivslam_cli.config import KEYS, SECTIONS, markdown_table, resolve_config
from ivslam_cli.errors import ConfigError


def write(tmp_path, text, name="c.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_defaults_are_the_table():
    cfg = resolve_config()
    for k in KEYS:
        assert cfg[k.dotted] == k.default
        assert cfg.sources[k.dotted] == "default"
    assert set(cfg.values) == set(SECTIONS)


def test_precedence_default_log_file_option(tmp_path):
    p = write(tmp_path, "[bounds]\nrange_abs = 0.2\nbearing = 0.01\n[pairs]\neps = 0.02\n")
    cfg = resolve_config(
        p,
        overrides={"bounds.bearing": 0.03, "pairs.eps": None, "robust.q_pair": 2},
        log_bounds={"range_abs": 0.5, "range_rel": 0.01, "gps_sigma": 3.0},
    )
    assert cfg["bounds.range_abs"] == 0.2 and cfg.sources["bounds.range_abs"] == str(p)  # file beats log
    assert cfg["bounds.range_rel"] == 0.01 and cfg.sources["bounds.range_rel"] == "log"  # log beats default
    assert cfg["bounds.bearing"] == 0.03 and cfg.sources["bounds.bearing"] == "option"  # option beats file
    assert cfg["pairs.eps"] == 0.02  # None = option not given
    assert cfg["robust.q_pair"] == 2
    assert cfg["bounds.odom_rot_abs"] == 0.0 and cfg.sources["bounds.odom_rot_abs"] == "default"
    assert cfg.ignored_log_bounds == ["gps_sigma"]


def test_types_are_normalised_and_json_safe(tmp_path):
    p = write(tmp_path, "[bounds]\nrange_abs = 1\n[pairs]\nheading = [-0.1, 0.1]\nanchor_id = 4\nanchor_xy = [1, 2.5]\n")
    cfg = resolve_config(p)
    assert isinstance(cfg["bounds.range_abs"], float) and cfg["bounds.range_abs"] == 1.0
    assert cfg["pairs.heading"] == (-0.1, 0.1)
    assert cfg["pairs.anchor_xy"] == (1.0, 2.5)
    d = cfg.as_dict()
    assert json.loads(json.dumps(d)) == d
    assert d["pairs"]["anchor_id"] == 4 and d["pairs"]["reference_id"] is None


@pytest.mark.parametrize(
    "text, match",
    [
        ("[bounds]\nrange_abss = 0.1\n", r"unknown key 'range_abss' in \[bounds\]"),
        ("[pairz]\neps = 0.1\n", "unknown section or top-level key 'pairz'"),
        ("eps = 0.1\n", "unknown section or top-level key 'eps'"),
        ("[bounds]\nrange_abs = 'big'\n", r"\[bounds\] range_abs must be a number"),
        ("[bounds]\nrange_abs = true\n", r"\[bounds\] range_abs must be a number"),
        ("[bounds]\nrange_abs = -0.1\n", r"range_abs must be >= 0"),
        ("[bounds]\nrange_abs = nan\n", "not NaN"),
        ("[robust]\nq_pair = 1.5\n", r"q_pair must be an integer"),
        ("[robust]\nstrict = 1\n", "strict must be true or false"),
        ("[pairs]\neps = 0\n", r"eps must be >= 1e-06"),
        ("[pairs]\nheading = [0.2, 0.1]\n", "lo <= hi"),
        ("[pairs]\nanchor_xy = [1]\n", "two numbers"),
        ("[lidar]\nresolution = 0.05\n", r"unknown key 'resolution' in \[lidar\] \(known: eps, max_range"),
        ("[bounds\n", "invalid TOML"),
    ],
)
def test_errors_name_key_and_file(tmp_path, text, match):
    p = write(tmp_path, text)
    with pytest.raises(ConfigError, match=match) as info:
        resolve_config(p)
    msg = str(info.value)
    assert msg.startswith(str(p) + ": ") and "\n" not in msg


def test_missing_and_binary_files(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        resolve_config(tmp_path / "nope.toml")
    bad = tmp_path / "b.toml"
    bad.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ConfigError, match="invalid TOML"):
        resolve_config(bad)


def test_bad_option_value_names_the_key():
    with pytest.raises(ConfigError, match=r"command line: \[robust\] q_pair must be an integer"):
        resolve_config(overrides={"robust.q_pair": "x"})
    with pytest.raises(ConfigError, match="unknown configuration key 'pairs.nope'"):
        resolve_config(overrides={"pairs.nope": 1})


def test_markdown_table_lists_every_key():
    md = markdown_table()
    for k in KEYS:
        assert f"| `{k.name}` |" in md
    for s in SECTIONS:
        assert f"[{s}]" in md
    out = subprocess.run(
        [sys.executable, "-m", "ivslam_cli.config", "--markdown"], capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == md.strip()
