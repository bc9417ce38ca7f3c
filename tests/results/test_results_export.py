"""Exports: TUM trajectories and ROS map_server maps parse back; atomic; no clobbering."""

from __future__ import annotations

import numpy as np
import pytest

from ivslam_cli.errors import IvslamError
from ivslam_cli.results.checksum import input_sha256
from ivslam_cli.results.example import example_result
from ivslam_cli.results.export import (
    PGM_FREE,
    PGM_OCCUPIED,
    PGM_UNKNOWN,
    write_map_server,
    write_tum,
)
from ivslam_cli.results.hdf5 import write_result
from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE, CELL_UNKNOWN, MapGrid

def read_pgm(path):
    data = path.read_bytes()
    tokens, pos = [], 0
    while len(tokens) < 4:  # magic, width, height, maxval (comments skipped)
        while data[pos : pos + 1].isspace():
            pos += 1
        if data[pos : pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while not data[end : end + 1].isspace():
            end += 1
        tokens.append(data[pos:end].decode())
        pos = end
    pos += 1  # the single whitespace after maxval
    magic, w, h, maxval = tokens[0], int(tokens[1]), int(tokens[2]), int(tokens[3])
    assert magic == "P5" and maxval == 255
    img = np.frombuffer(data[pos:], dtype=np.uint8)
    assert img.size == w * h
    return img.reshape(h, w)

def read_simple_yaml(path):
    out = {}
    for line in path.read_text().splitlines():
        key, _, value = line.partition(":")
        value = value.strip()
        if value.startswith("["):
            out[key] = [float(v) for v in value.strip("[]").split(",")]
        else:
            try:
                out[key] = float(value)
            except ValueError:
                out[key] = value
    return out

def test_tum_round_trip(tmp_path):
    r = example_result()
    r.poses.box[2] = [[np.inf, -np.inf]] * 3  # an empty box has no centre
    r.poses.box[4, 2] = [2.9, 3.3]  # heading 3.1 rad
    path = tmp_path / "traj.txt"
    assert write_tum(path, r.poses) == 1
    rows = np.loadtxt(path)
    assert rows.shape == (5, 8)
    keep = [0, 1, 3, 4, 5]
    np.testing.assert_array_equal(rows[:, 0], r.poses.stamp[keep])
    centre = 0.5 * (r.poses.box[keep, :, 0] + r.poses.box[keep, :, 1])
    np.testing.assert_array_equal(rows[:, 1:3], centre[:, :2])
    assert np.all(rows[:, 3:6] == 0)
    np.testing.assert_allclose(np.linalg.norm(rows[:, 4:8], axis=1), 1.0)
    yaw = 2 * np.arctan2(rows[:, 6], rows[:, 7])
    np.testing.assert_allclose(yaw, centre[:, 2], atol=1e-12)
    with pytest.raises(IvslamError, match="--force"):
        write_tum(path, r.poses)

def test_map_server_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    state = rng.choice([CELL_UNKNOWN, CELL_EMPTY, CELL_OBSTACLE], size=(7, 11)).astype(np.uint8)
    grid = MapGrid(origin=np.array([-2.5, 0.1]), resolution=0.05, state=state)
    pgm, yml = write_map_server(tmp_path / "map", grid)
    img = read_pgm(pgm)
    assert img.shape == (7, 11)
    # image row 0 is the top of the map (largest y)
    expect = np.where(state == CELL_EMPTY, PGM_FREE, np.where(state == CELL_OBSTACLE, PGM_OCCUPIED, PGM_UNKNOWN))
    np.testing.assert_array_equal(img, expect[::-1])
    y = read_simple_yaml(yml)
    assert y["image"] == "map.pgm" and y["mode"] == "trinary"
    assert y["resolution"] == 0.05 and y["origin"] == [-2.5, 0.1, 0.0]
    assert y["negate"] == 0 and y["occupied_thresh"] == 0.65 and y["free_thresh"] == 0.196
    # map_server's trinary reading: p = (255 - v)/255; occupied if p > occ, free if p < free
    p = (255 - img.astype(float)) / 255
    assert np.all((p > y["occupied_thresh"]) == (expect[::-1] == PGM_OCCUPIED))
    assert np.all((p < y["free_thresh"]) == (expect[::-1] == PGM_FREE))
    with pytest.raises(IvslamError, match="--force"):
        write_map_server(tmp_path / "map", grid)
    write_map_server(tmp_path / "map", grid, force=True)

def test_map_pgm_refuses_if_either_file_exists(tmp_path):
    (tmp_path / "m.yaml").write_text("keep")
    with pytest.raises(IvslamError, match="m.yaml"):
        write_map_server(tmp_path / "m", example_result().grid)
    assert not (tmp_path / "m.pgm").exists() and (tmp_path / "m.yaml").read_text() == "keep"

def test_cli_exports(cli_run, tmp_path):
    write_result(tmp_path / "r.h5", example_result())
    res = cli_run("report", tmp_path / "r.h5", "--tum", tmp_path / "t.txt", "--map-pgm", tmp_path / "m")
    assert res.exit_code == 0, res.output
    assert np.loadtxt(tmp_path / "t.txt").shape == (6, 8)
    assert read_pgm(tmp_path / "m.pgm").shape == (4, 5)
    r = example_result(with_grid=False)
    write_result(tmp_path / "ng.h5", r)
    res = cli_run("report", tmp_path / "ng.h5", "--map-pgm", tmp_path / "x")
    assert res.exit_code != 0 and "no map grid" in res.output

def test_input_sha256_file_and_directory(tmp_path):
    f = tmp_path / "a.bin"
    f.write_bytes(b"abc")
    assert input_sha256(f) == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    d = tmp_path / "bag"
    (d / "sub").mkdir(parents=True)
    (d / "x.db3").write_bytes(b"1")
    (d / "sub" / "metadata.yaml").write_bytes(b"2")
    h0 = input_sha256(d)
    assert h0 == input_sha256(d) and len(h0) == 64
    (d / "x.db3").write_bytes(b"3")
    h1 = input_sha256(d)
    assert h1 != h0
    (d / "x.db3").rename(d / "y.db3")
    assert input_sha256(d) != h1


def test_make_provenance_from_a_log(tmp_path):
    from ivslam_cli.config import resolve_config
    from ivslam_cli.logs.model import Dropped, Provenance
    from ivslam_cli.results.provenance import make_provenance

    log = tmp_path / "x.log"
    log.write_bytes(b"abc")
    p = make_provenance(
        Provenance(str(log), "carmen", {"scans": "FLASER"}, [Dropped("scans", 3, "NaN range")], ["n"]),
        resolve_config(overrides={"robust.q_pair": 2}).as_dict(),
        ["run", str(log), "--mode", "pairs", "-o", "a b.h5"],
    )
    assert p.input_sha256 == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    assert p.command == f"ivslam run {log} --mode pairs -o 'a b.h5'"
    assert p.config["robust"]["q_pair"] == 2 and p.dropped[0].count == 3 and p.input_format == "carmen"
