"""The package's import: the kernel cache directory, keyed by the sources that hold numba code."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import ivslam_cli


def test_the_cache_key_hashes_every_numba_source_in_path_order(monkeypatch, tmp_path):
    root = Path(ivslam_cli.__file__).resolve().parent
    digest = hashlib.sha1(ivslam_cli.__version__.encode())
    for path in sorted(root.rglob("*.py")):
        text = path.read_bytes()
        if b"numba" in text:
            digest.update(path.relative_to(root).as_posix().encode())
            digest.update(text)
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    ivslam_cli._set_numba_cache_dir()
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "ivslam" / "numba" / digest.hexdigest()[:16])


def test_a_cache_directory_given_is_kept(monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", "/somewhere/else")
    ivslam_cli._set_numba_cache_dir()
    assert os.environ["NUMBA_CACHE_DIR"] == "/somewhere/else"
