"""Deep equality of results (and of anything made of dataclasses, arrays, dicts and sequences)."""

from __future__ import annotations

import dataclasses

import numpy as np


def assert_same(a, b, where="result"):
    """Deep equality: dataclasses field by field, arrays by dtype kind, shape and value."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray), where
        assert a.shape == b.shape, f"{where}: shape {a.shape} != {b.shape}"
        assert a.dtype.kind == b.dtype.kind, f"{where}: dtype {a.dtype} != {b.dtype}"
        if a.dtype.kind == "f":
            assert a.dtype == b.dtype, where
            assert np.array_equal(a, b, equal_nan=True), where
        else:
            assert np.array_equal(a, b), where
    elif isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f"{where}: keys {set(a)} != {set(b)}"
        for k in a:
            assert_same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{k}]")
    elif isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return  # NaN == NaN here: the same missing value
    else:
        assert type(a) is type(b) and a == b, f"{where}: {a!r} != {b!r}"
