"""Decoding of float16 and snorm16 response arrays, against arrays encoded here by the
proto's formulas (the decoder alone; test_crowds_and_encodings.py takes every encoding
through a real server)."""
import numpy as np
import pytest

from skinserve import decode_values
from skinserve._encoding import FLOAT16, FLOAT32, SNORM16


def test_float32_is_exact():
    x = np.array([[1.5, -2.25, 3e-8], [7, 8, 9]], dtype=np.float32)
    assert np.array_equal(decode_values(x.astype("<f4").tobytes(), FLOAT32, 2), x)


def test_float16_within_half_an_ulp():
    rng = np.random.default_rng(1)
    x = rng.uniform(-1000, 1000, size=(100, 3))
    data = x.astype("<f2").tobytes()  # round to nearest even, as the server does
    got = decode_values(data, FLOAT16, 100)
    assert got.dtype == np.float32
    assert np.all(np.abs(got - x) <= np.abs(x) * 2.0 ** -11)


def test_snorm16_positions_within_half_a_step():
    rng = np.random.default_rng(2)
    lo, hi = np.array([-3.0, 0.5, -10.0]), np.array([5.0, 0.5, 2.0])  # y: a flat box, h = 0
    x = rng.uniform(lo, hi, size=(500, 3))
    x[0], x[1] = lo, hi  # the box's corners map to -32767 and 32767
    c, h = (lo + hi) / 2, (hi - lo) / 2
    q = np.where(h > 0, np.round((x - c) / np.where(h > 0, h, 1) * 32767), 0)
    assert q.min() >= -32767 and q.max() <= 32767
    bounds = (*lo, *hi)
    got = decode_values(q.astype("<i2").tobytes(), SNORM16, 500, bounds)
    step = (hi - lo) / 131068  # half a step per axis
    assert np.all(np.abs(got - x) <= step + 1e-6 * (1 + np.abs(x)))
    assert np.all(got[:, 1] == np.float32(0.5))
    assert np.array_equal(got[0], lo.astype(np.float32))


def test_snorm16_normals():
    rng = np.random.default_rng(3)
    n = rng.normal(size=(200, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    q = np.round(n * 32767).astype("<i2")
    got = decode_values(q.tobytes(), SNORM16, 200, normals=True)
    assert np.all(np.abs(got - n) <= 1 / 65534 + 1e-7)


def test_wrong_sizes_are_refused():
    with pytest.raises(ValueError, match="holds 5 values, expected 6"):
        decode_values(np.zeros(5, "<f4").tobytes(), FLOAT32, 2)
    with pytest.raises(ValueError, match="without bounds"):
        decode_values(np.zeros(3, "<i2").tobytes(), SNORM16, 1)
