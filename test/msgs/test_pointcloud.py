"""sensor_msgs/PointCloud2 <-> structured arrays, for any dtype; record dtypes; malformed clouds."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sonar_tracking.msgs import (
    DETECTION_DTYPE,
    GPF_TRACK_DTYPE,
    RECORD_DTYPES,
    REGION_DTYPE,
    TRACK_DTYPE,
    TRUTH_DTYPE,
    AdapterError,
    array_to_cloud,
    cloud_to_array,
    dtype_to_fields,
)
from sonar_tracking.msgs.pointcloud import DATATYPES

BASES = [np.dtype(d) for d in ('i1', 'u1', 'i2', 'u2', 'i4', 'u4', 'f4', 'f8')]


def fill(dtype: np.dtype, n: int, rng: np.random.Generator) -> np.ndarray:
    a = np.zeros(n, dtype)
    for name in dtype.names:
        base, shape = dtype[name].base, dtype[name].shape
        size = (n,) + shape
        if base.kind == 'f':
            a[name] = rng.normal(scale=1e3, size=size)
        else:
            info = np.iinfo(base)
            a[name] = rng.integers(info.min, info.max, size=size, endpoint=True)
    return a


@st.composite
def record_dtypes(draw):
    n = draw(st.integers(1, 6))
    names = draw(st.lists(st.from_regex(r'[a-z][a-z0-9_]{0,7}', fullmatch=True), min_size=n, max_size=n,
                          unique=True))
    formats, offsets, off = [], [], 0
    for _ in names:
        base = draw(st.sampled_from(BASES))
        count = draw(st.integers(1, 3))
        off += draw(st.integers(0, 3))  # gaps: unaligned and padded layouts
        fmt = base if count == 1 else np.dtype((base, (count,)))
        formats.append(fmt)
        offsets.append(off)
        off += fmt.itemsize
    order = draw(st.permutations(range(n)))
    return np.dtype({'names': [names[i] for i in order], 'formats': [formats[i] for i in order],
                     'offsets': [offsets[i] for i in order], 'itemsize': off + draw(st.integers(0, 4))})


@settings(max_examples=150, deadline=None)
@given(dtype=record_dtypes(), n=st.integers(0, 40), seed=st.integers(0, 2**32 - 1))
def test_property_round_trip_any_dtype(dtype, n, seed):
    a = fill(dtype, n, np.random.default_rng(seed))
    msg = array_to_cloud(a, stamp_ns=7, frame_id='world')
    b = cloud_to_array(msg)
    assert msg.height == 1 and msg.width == n and b.shape == (n,)
    assert b.dtype.names == a.dtype.names
    for name in a.dtype.names:
        assert np.array_equal(a[name], b[name])


@settings(max_examples=60, deadline=None)
@given(dtype=record_dtypes(), h=st.integers(1, 4), w=st.integers(1, 10), pad=st.integers(0, 9),
       seed=st.integers(0, 2**32 - 1))
def test_property_big_endian_and_row_padding(dtype, h, w, pad, seed):
    a = fill(dtype, h * w, np.random.default_rng(seed)).reshape(h, w)
    big = a.astype(a.dtype.newbyteorder('>'))
    rows = [big[r].tobytes() + bytes(pad) for r in range(h)]
    fields = [SimpleNamespace(name=n, offset=o, datatype=d, count=c) for n, o, d, c in dtype_to_fields(dtype)]
    msg = SimpleNamespace(height=h, width=w, fields=fields, is_bigendian=True, point_step=dtype.itemsize,
                          row_step=w * dtype.itemsize + pad, data=b''.join(rows), is_dense=True)
    b = cloud_to_array(msg)
    assert b.shape == ((w,) if h == 1 else (h, w))  # unorganized clouds come back 1-D
    for name in dtype.names:
        assert np.array_equal(a[name].reshape(b.shape + a[name].shape[2:]), b[name])


@pytest.mark.parametrize('dtype', list(RECORD_DTYPES.values()), ids=list(RECORD_DTYPES))
def test_record_dtypes_round_trip_both_message_kinds(dtype, types):
    a = fill(dtype, 25, np.random.default_rng(3))
    b = cloud_to_array(array_to_cloud(a, types=types))
    assert b.dtype == dtype and np.array_equal(a, b)


@pytest.mark.parametrize('dtype', [DETECTION_DTYPE, TRACK_DTYPE], ids=['detections', 'tracks'])
def test_width_zero_round_trips_with_fields(dtype, types):
    msg = array_to_cloud(np.zeros(0, dtype), types=types)
    assert msg.width == 0 and msg.height == 1 and len(msg.fields) == len(dtype.names)
    b = cloud_to_array(msg)
    assert b.shape == (0,) and b.dtype == dtype


def test_record_dtypes_match_design():
    assert DETECTION_DTYPE.names == ('x', 'y', 'range', 'bearing', 'amplitude', 'clutter_density',
                                     'cov_xx', 'cov_xy', 'cov_yy')
    assert TRACK_DTYPE.names == ('track_id', 'x', 'y', 'vx', 'vy', 'existence', 'confirmed', 'mode_cv',
                                 'mode_ccw', 'mode_cw', 'cov_xx', 'cov_xy', 'cov_yy', 'cov_vxvx', 'cov_vyvy')
    assert TRACK_DTYPE['track_id'] == np.dtype('<u4') and TRACK_DTYPE['confirmed'] == np.dtype('u1')
    assert TRUTH_DTYPE.names == ('target_id', 'x', 'y', 'vx', 'vy')
    assert REGION_DTYPE.names[:5] == ('region_id', 'x', 'y', 'range', 'bearing')
    assert REGION_DTYPE.names[5:] == tuple(f'f{i:02d}' for i in range(1, 31))
    assert GPF_TRACK_DTYPE.names[:7] == ('track_id', 'x', 'y', 'vx', 'vy', 'confirmed', 'fusion')


def test_dense_flag_reflects_nan():
    a = np.zeros(3, DETECTION_DTYPE)
    assert array_to_cloud(a).is_dense
    a['x'][1] = np.nan
    assert not array_to_cloud(a).is_dense


def test_read_is_read_only():
    b = cloud_to_array(array_to_cloud(np.zeros(4, TRUTH_DTYPE)))
    with pytest.raises(ValueError):
        b['x'][0] = 1.0


def good_cloud(**changes):
    a = fill(TRUTH_DTYPE, 3, np.random.default_rng(0))
    fields = [SimpleNamespace(name=n, offset=o, datatype=d, count=c) for n, o, d, c in dtype_to_fields(TRUTH_DTYPE)]
    msg = dict(height=1, width=3, fields=fields, is_bigendian=False, point_step=TRUTH_DTYPE.itemsize,
               row_step=3 * TRUTH_DTYPE.itemsize, data=a.tobytes(), is_dense=True)
    msg.update(changes)
    return SimpleNamespace(**msg)


def field(name, offset, datatype, count=1):
    return SimpleNamespace(name=name, offset=offset, datatype=datatype, count=count)


@pytest.mark.parametrize('changes, match', [
    ({'fields': [field('x', 0, 9)]}, 'unknown PointField datatype 9'),
    ({'fields': [field('x', 0, 8), field('y', 4, 8)]}, 'overlap'),
    ({'fields': [field('x', 0, 8), field('x', 8, 8)]}, 'appears twice'),
    ({'fields': [field('x', 30, 8)]}, 'does not fit in point_step'),
    ({'fields': [field('x', 0, 8, 0)]}, 'count 0'),
    ({'data': bytes(10)}, 'data is short'),
    ({'row_step': 10}, 'row_step = 10 is shorter'),
    ({'point_step': 0}, 'point_step = 0'),
])
def test_malformed_clouds_raise_clear_errors(changes, match):
    with pytest.raises(AdapterError, match=match):
        cloud_to_array(good_cloud(**changes))


def test_not_a_cloud():
    with pytest.raises(AdapterError, match='not a sensor_msgs/PointCloud2'):
        cloud_to_array(SimpleNamespace(height=1))


@pytest.mark.parametrize('dtype, match', [
    (np.dtype(np.float64), 'structured dtype'),
    (np.dtype([('a', 'i8')]), 'PointField cannot hold'),
    (np.dtype([('a', '?')]), 'PointField cannot hold'),
    (np.dtype([('a', 'f4', (2, 2))]), 'multi-dimensional'),
    (np.dtype([('a', [('b', 'f4')])]), 'PointField cannot hold'),
])
def test_unsupported_dtypes_refused(dtype, match):
    with pytest.raises(AdapterError, match=match):
        array_to_cloud(np.zeros(2, dtype))


def test_datatype_table_is_pointfield_numbering():
    from sensor_msgs.msg import PointField
    assert {PointField.INT8: np.dtype('i1'), PointField.UINT8: np.dtype('u1'),
                         PointField.INT16: np.dtype('i2'), PointField.UINT16: np.dtype('u2'),
                         PointField.INT32: np.dtype('i4'), PointField.UINT32: np.dtype('u4'),
                         PointField.FLOAT32: np.dtype('f4'), PointField.FLOAT64: np.dtype('f8')} == DATATYPES


def test_serialized_cloud_crosses_between_rclpy_and_rosbags(rosbags_types):
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import PointCloud2
    a = fill(TRACK_DTYPE, 11, np.random.default_rng(5))
    ts = rosbags_types.typestore
    from_bag = ts.deserialize_cdr(serialize_message(array_to_cloud(a)), 'sensor_msgs/msg/PointCloud2')
    assert np.array_equal(cloud_to_array(from_bag), a)
    raw = bytes(ts.serialize_cdr(array_to_cloud(a, types=rosbags_types), 'sensor_msgs/msg/PointCloud2'))
    assert np.array_equal(cloud_to_array(deserialize_message(raw, PointCloud2)), a)
