"""sensor_msgs/Image <-> numpy: round trips, padded and byte-swapped layouts, malformed messages."""
from __future__ import annotations

import sys
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sonar_tracking.msgs import ENCODING_DTYPES, AdapterError, array_to_image, image_to_array


def raw_image(a: np.ndarray, encoding: str, pad: int = 0, bigendian: bool = False, data=None):
    """A message-like object laid out by hand: rows padded by ``pad`` bytes, chosen byte order."""
    dt = ENCODING_DTYPES[encoding].newbyteorder('>' if bigendian else '<')
    rows = [a[r].astype(dt).tobytes() + bytes(pad) for r in range(a.shape[0])]
    return SimpleNamespace(height=a.shape[0], width=a.shape[1], encoding=encoding,
                           is_bigendian=int(bigendian), step=a.shape[1] * dt.itemsize + pad,
                           data=b''.join(rows) if data is None else data)


def sample(shape, encoding, rng):
    dt = ENCODING_DTYPES[encoding]
    if dt.kind == 'f':
        return rng.normal(size=shape).astype(dt)
    return rng.integers(0, np.iinfo(dt).max, size=shape, endpoint=True).astype(dt)


@pytest.mark.parametrize('encoding', sorted(ENCODING_DTYPES))
def test_round_trip_each_encoding(encoding, types):
    a = sample((17, 23), encoding, np.random.default_rng(0))
    msg = array_to_image(a, encoding, stamp_ns=1_500_000_123, frame_id='sonar', types=types)
    assert msg.encoding == encoding and msg.step == 23 * a.dtype.itemsize
    assert msg.header.frame_id == 'sonar'
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1, 500_000_123)
    b = image_to_array(msg)
    assert b.dtype == a.dtype and np.array_equal(a, b)


def test_default_encoding_from_dtype():
    assert array_to_image(np.zeros((2, 3), np.uint8)).encoding == 'mono8'
    assert array_to_image(np.zeros((2, 3), np.uint16)).encoding == 'mono16'
    assert array_to_image(np.zeros((2, 3), np.float32)).encoding == '32FC1'


def test_read_is_a_read_only_view_of_the_message():
    msg = array_to_image(np.arange(12, dtype=np.float32).reshape(3, 4))
    a = image_to_array(msg)
    assert not a.flags.writeable
    assert np.shares_memory(a, np.frombuffer(msg.data, np.uint8))


@settings(max_examples=150, deadline=None)
@given(h=st.integers(1, 30), w=st.integers(1, 30), encoding=st.sampled_from(sorted(ENCODING_DTYPES)),
       pad_px=st.integers(0, 5), bigendian=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_padded_and_byte_swapped_layouts(h, w, encoding, pad_px, bigendian, seed):
    a = sample((h, w), encoding, np.random.default_rng(seed))
    msg = raw_image(a, encoding, pad=pad_px * a.dtype.itemsize, bigendian=bigendian)
    b = image_to_array(msg)
    assert b.shape == (h, w) and b.dtype == a.dtype
    assert np.array_equal(a, b, equal_nan=a.dtype.kind == 'f')


@settings(max_examples=100, deadline=None)
@given(h=st.integers(1, 40), w=st.integers(1, 40), encoding=st.sampled_from(sorted(ENCODING_DTYPES)),
       seed=st.integers(0, 2**32 - 1), fortran=st.booleans())
def test_property_round_trip(h, w, encoding, seed, fortran):
    a = sample((h, w), encoding, np.random.default_rng(seed))
    if fortran:
        a = np.asfortranarray(a)
    assert np.array_equal(image_to_array(array_to_image(a, encoding)), a)


def test_float64_is_stored_as_32fc1():
    a = np.linspace(0, 1, 6).reshape(2, 3)
    b = image_to_array(array_to_image(a, '32FC1'))
    assert b.dtype == np.float32 and np.allclose(a, b)


@pytest.mark.parametrize('make, match', [
    (lambda: raw_image(np.zeros((2, 2), np.uint8), 'mono8').__dict__ | {'encoding': 'rgb8'},
     'unsupported image encoding'),
    (lambda: raw_image(np.zeros((2, 2), np.uint8), 'mono8').__dict__ | {'data': bytes(3)}, 'data is short'),
    (lambda: raw_image(np.zeros((2, 2), np.uint8), 'mono8').__dict__ | {'data': bytes(5)},
     'does not match|step \\* height'),
    (lambda: raw_image(np.zeros((2, 2), np.uint16), 'mono16').__dict__ | {'step': 3}, 'shorter than a row'),
    (lambda: raw_image(np.zeros((2, 2), np.uint16), 'mono16', pad=1).__dict__, 'not a multiple'),
    (lambda: raw_image(np.zeros((2, 2), np.uint8), 'mono8').__dict__ | {'height': 0, 'data': b''}, 'zero size'),
    (lambda: raw_image(np.zeros((2, 2), np.uint8), 'mono8').__dict__ | {'width': 0}, 'zero size'),
])
def test_malformed_images_raise_clear_errors(make, match):
    with pytest.raises(AdapterError, match=match):
        image_to_array(SimpleNamespace(**make()))


def test_not_an_image():
    with pytest.raises(AdapterError, match='not a sensor_msgs/Image'):
        image_to_array(SimpleNamespace(height=1))


@pytest.mark.parametrize('array, encoding, match', [
    (np.zeros((2, 2), np.float64), None, 'no image encoding for dtype'),
    (np.zeros((2, 2), np.float32), 'mono8', 'without changing its kind'),
    (np.zeros((2, 2, 3), np.uint8), None, '2-D'),
    (np.zeros((0, 4), np.uint8), None, 'zero size'),
    (np.zeros((2, 2), np.uint8), 'bgr8', 'unsupported'),
])
def test_bad_arrays_refused(array, encoding, match):
    with pytest.raises(AdapterError, match=match):
        array_to_image(array, encoding)


def test_written_byte_order_is_the_machines():
    msg = array_to_image(np.zeros((1, 1), np.uint16))
    assert bool(msg.is_bigendian) == (sys.byteorder == 'big')
