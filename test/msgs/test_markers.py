"""Track MarkerArray: DELETEALL first, sphere/label/arrow/ellipse per track, ellipse geometry."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.msgs import GPF_TRACK_DTYPE, TRACK_DTYPE, AdapterError, covariance_ellipse, track_markers

ARROW, SPHERE, CYLINDER, TEXT, DELETEALL = 0, 2, 3, 9, 3


def tracks(n=3):
    t = np.zeros(n, TRACK_DTYPE)
    t['track_id'] = np.arange(1, n + 1)
    t['x'] = np.arange(n) * 10.0
    t['y'] = 5.0
    t['vx'] = 2.0
    t['vy'] = -1.0
    t['cov_xx'], t['cov_yy'] = 4.0, 1.0
    t['confirmed'] = [1] + [0] * (n - 1)
    return t


def test_structure(types):
    ma = track_markers(tracks(), stamp_ns=5, frame_id='world', scale=2.0, arrow_seconds=3.0, types=types)
    m = ma.markers
    assert m[0].action == DELETEALL
    assert len(m) == 1 + 4 * 3
    by_ns = {}
    for k in m[1:]:
        by_ns.setdefault(k.ns, []).append(k)
        assert k.header.frame_id == 'world' and k.header.stamp.nanosec == 5
    assert sorted(by_ns) == ['tracks/covariance', 'tracks/label', 'tracks/position', 'tracks/velocity']
    assert [k.id for k in by_ns['tracks/position']] == [1, 2, 3]
    assert all(k.type == SPHERE and k.scale.x == 2.0 for k in by_ns['tracks/position'])
    assert [k.text for k in by_ns['tracks/label']] == ['T1', 'T2', 'T3']
    arrow = by_ns['tracks/velocity'][1]
    assert arrow.type == ARROW
    assert (arrow.points[0].x, arrow.points[0].y) == (10.0, 5.0)
    assert (arrow.points[1].x, arrow.points[1].y) == (16.0, 2.0)
    confirmed, tentative = by_ns['tracks/position'][0].color, by_ns['tracks/position'][1].color
    assert confirmed.g > 0.8 and tentative.g < 0.7


def test_ellipse_axes_and_orientation():
    major, minor, yaw = covariance_ellipse(4.0, 0.0, 1.0, n_sigma=2.0)
    assert (major, minor) == pytest.approx((8.0, 4.0)) and math.sin(yaw) == pytest.approx(0.0, abs=1e-12)
    # Rotated by 45 degrees: eigenvalues 3 and 1 along (1, 1) and (1, -1).
    major, minor, yaw = covariance_ellipse(2.0, 1.0, 2.0, n_sigma=1.0)
    assert (major, minor) == pytest.approx((2 * math.sqrt(3), 2.0))
    assert math.tan(yaw) == pytest.approx(1.0)
    cyl = [k for k in track_markers(tracks(1)).markers if k.ns == 'tracks/covariance'][0]
    assert cyl.type == CYLINDER and cyl.scale.x == pytest.approx(8.0) and cyl.scale.y == pytest.approx(4.0)


def test_non_positive_definite_covariance_is_clipped():
    major, minor, _ = covariance_ellipse(1.0, 2.0, 1.0)
    assert minor == 0.0 and math.isfinite(major)


def test_nan_tracks_are_skipped_and_empty_still_clears():
    t = tracks(2)
    t['x'][0] = np.nan
    assert len(track_markers(t).markers) == 1 + 4
    empty = track_markers(np.zeros(0, TRACK_DTYPE)).markers
    assert len(empty) == 1 and empty[0].action == DELETEALL


def test_gpf_records_work_and_missing_fields_refused():
    g = np.zeros(1, GPF_TRACK_DTYPE)
    g['cov_xx'] = g['cov_yy'] = 1.0
    assert len(track_markers(g, ns='gpf').markers) == 5
    with pytest.raises(AdapterError, match='lack'):
        track_markers(np.zeros(1, [('x', 'f8'), ('y', 'f8')]))


def test_large_ids_fit_marker_int32():
    t = tracks(1)
    t['track_id'] = 2**32 - 1
    ids = {k.id for k in track_markers(t).markers[1:]}
    assert ids == {(2**32 - 1) % 2**31}
