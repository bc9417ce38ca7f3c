"""Typestores: a file's embedded definitions are enough to read it, and give the same log."""

from __future__ import annotations

import dataclasses

import pytest

import ivslam_cli.logs.mcap_file as mcap_file
from ivslam_cli.logs import read_log
from ivslam_cli.logs.typestore import typestore, typestore_from_schemas
from tests.helpers.paths import SAMPLE_LOGS
from tests.helpers.results import assert_same

STRING = ("std_msgs/msg/String", "ros2msg", b"string data\n")


def test_a_store_of_the_embedded_definitions():
    store = typestore_from_schemas(2, [STRING], ["std_msgs/msg/String"])
    assert store is not typestore(2)
    assert "std_msgs/msg/String" in store.types and "ivslam_msgs/msg/LandmarkObservations" in store.types
    assert "sensor_msgs/msg/LaserScan" not in store.types


@pytest.mark.parametrize("schemas,wanted", [
    ([STRING], ["sensor_msgs/msg/LaserScan"]),  # a wanted type the file does not define
    ([("std_msgs/msg/String", "ros2msg", b"strin g data [\n")], ["std_msgs/msg/String"]),  # not a definition
    ([("std_msgs/msg/String", "ros2msg", b"\xff\xfe")], ["std_msgs/msg/String"]),  # not text
    ([("std_msgs/msg/String", "ros1msg", b"string data\n")], ["std_msgs/msg/String"]),  # another profile's
])
def test_the_full_store_when_the_file_does_not_define_what_is_read(schemas, wanted):
    assert typestore_from_schemas(2, schemas, wanted) is typestore(2)


@pytest.mark.parametrize("name", ["pairs.mcap", "lidar_corridor.mcap"])
def test_reading_with_the_embedded_definitions_gives_the_same_log(name, monkeypatch):
    path = SAMPLE_LOGS / name
    new = read_log(path)
    monkeypatch.setattr(mcap_file, "typestore_from_schemas", lambda ros, schemas, wanted: typestore(ros))
    old = read_log(path)
    for f in dataclasses.fields(new):
        if f.name != "provenance":
            assert_same(getattr(new, f.name), getattr(old, f.name), f.name)
