"""Sector geometry (LaserScan) <-> SectorGeometry, and pairing sector Images with their geometry."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from sonar_tracking.core.sector import GeometryError, SectorGeometry
from sonar_tracking.msgs import (
    AdapterError,
    SectorPairer,
    array_to_image,
    geometry_to_scan,
    scan_to_geometry,
    sector_from_messages,
)

GEOM = SectorGeometry(angle_min=-0.6, angle_increment=0.006, n_beams=200, range_min=500.0,
                      range_max=4000.0, n_bins=201, ping_period=0.005, scan_time=1.0)


def test_round_trip(types):
    amps = np.random.default_rng(0).exponential(size=GEOM.shape).astype(np.float32)
    amps[37, 5] = 100.0
    scan = geometry_to_scan(GEOM, amplitudes=amps, stamp_ns=42, frame_id='sonar', types=types)
    g = scan_to_geometry(scan, GEOM.n_bins)
    assert g.n_beams == GEOM.n_beams and g.n_bins == GEOM.n_bins
    for name in ('angle_min', 'angle_increment', 'range_min', 'range_max', 'ping_period', 'scan_time'):
        assert math.isclose(getattr(g, name), getattr(GEOM, name), rel_tol=1e-6), name
    assert math.isclose(scan.angle_max, GEOM.angle_max, rel_tol=1e-6)
    # The LaserScan payload is the strongest return of each beam.
    assert math.isclose(scan.ranges[5], GEOM.ranges()[37], rel_tol=1e-6)
    assert scan.intensities[5] == pytest.approx(100.0)


@settings(max_examples=100, deadline=None)
@given(amin=st.floats(-3.1, 3.0), inc=st.floats(1e-4, 0.05), n=st.integers(1, 400),
       rmin=st.floats(0.0, 100.0), span=st.floats(0.5, 5000.0), bins=st.integers(2, 800))
def test_property_geometry_survives_float32_fields(amin, inc, n, rmin, span, bins):
    assume((n - 1) * inc <= 2 * math.pi)
    g = SectorGeometry(angle_min=amin, angle_increment=inc, n_beams=n, range_min=rmin,
                       range_max=rmin + span, n_bins=bins)
    back = scan_to_geometry(geometry_to_scan(g), bins)
    assert back.n_beams == n
    assert np.allclose(back.bearings(), g.bearings(), atol=1e-5)
    assert np.allclose(back.ranges(), g.ranges(), rtol=1e-6, atol=1e-4)


def test_angle_max_inconsistent_with_beam_count():
    scan = geometry_to_scan(GEOM)
    scan.angle_max = GEOM.angle_max + GEOM.angle_increment
    with pytest.raises(AdapterError, match='angle_max'):
        scan_to_geometry(scan, GEOM.n_bins)


@pytest.mark.parametrize('change, match', [
    ({'angle_increment': 0.0}, 'angle_increment'),
    ({'range_min': -1.0}, 'range'),
    ({'range_max': float('nan')}, 'not finite'),
])
def test_bad_geometry_refused(change, match):
    scan = geometry_to_scan(GEOM)
    for k, v in change.items():
        setattr(scan, k, v)
    with pytest.raises(AdapterError, match=match):
        scan_to_geometry(scan, GEOM.n_bins)


def test_no_beams():
    scan = SimpleNamespace(angle_min=0.0, angle_max=0.0, angle_increment=0.1, time_increment=0.0, scan_time=0.0,
                           range_min=0.0, range_max=1.0, ranges=[], intensities=[])
    with pytest.raises(AdapterError, match='n_beams'):
        scan_to_geometry(scan, 10)


def test_sector_from_messages_checks_shape_and_stamp():
    amps = np.ones(GEOM.shape, np.float32)
    img = array_to_image(amps, stamp_ns=10)
    a, g = sector_from_messages(img, geometry_to_scan(GEOM, stamp_ns=10))
    assert a.shape == GEOM.shape and g == scan_to_geometry(geometry_to_scan(GEOM), GEOM.n_bins)
    with pytest.raises(AdapterError, match='differs'):
        sector_from_messages(img, geometry_to_scan(GEOM, stamp_ns=11))
    narrow = array_to_image(np.ones((GEOM.n_bins, 10), np.float32), stamp_ns=10)
    with pytest.raises(AdapterError, match='10 beams'):
        sector_from_messages(narrow, geometry_to_scan(GEOM, stamp_ns=10))


def test_strongest_returns_shape_check():
    with pytest.raises(GeometryError, match='shape'):
        GEOM.strongest_returns(np.zeros((3, 3)))


def msg(stamp_ns):
    return SimpleNamespace(header=SimpleNamespace(stamp=SimpleNamespace(sec=stamp_ns // 10**9,
                                                                        nanosec=stamp_ns % 10**9)))


def test_pairer_either_order_and_stale_drop():
    p = SectorPairer(max_pending=4)
    assert p.add_image(msg(1)) is None
    pair = p.add_info(msg(1))
    assert pair is not None and pair.stamp_ns == 1
    assert p.add_info(msg(2)) is None
    assert p.add_image(msg(3)) is None  # its info will never come
    pair = p.add_image(msg(2))
    assert pair.stamp_ns == 2 and p.pop_dropped() == []
    assert p.add_info(msg(4)) is None
    assert p.add_image(msg(4)).stamp_ns == 4
    assert p.pop_dropped() == [(3, ('image',))]


def test_pairer_bounded_pending():
    p = SectorPairer(max_pending=2)
    for s in (1, 2, 3):
        p.add_image(msg(s))
    assert p.pop_dropped() == [(1, ('image',))]
    assert p.add_info(msg(1)) is None


def test_pairer_time_going_backwards_still_pairs():
    p = SectorPairer()
    p.add_image(msg(100))
    p.add_info(msg(100))
    p.add_image(msg(5))
    assert p.add_info(msg(5)).stamp_ns == 5
