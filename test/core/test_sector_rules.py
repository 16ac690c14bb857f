"""The one sector rule of every consumer: physical bounds on geometry, values that can be echoes."""
import math

import numpy as np
import pytest

from sonar_tracking.core.sector import GeometryError, SectorError, SectorGeometry, check_sector


def geom(**kw):
    base = dict(angle_min=-0.5, angle_increment=0.01, n_beams=101, range_min=1.0, range_max=50.0, n_bins=200)
    return SectorGeometry(**(base | kw))


@pytest.mark.parametrize('kw, match', [
    (dict(range_max=3e38), 'beyond any sonar'),
    (dict(angle_increment=1e-30), 'finer than'),
    (dict(angle_increment=1e-5), 'finer than'),
    (dict(angle_increment=0.1, n_beams=64), 'more than a full turn'),
    (dict(n_beams=60000, angle_increment=1e-4, n_bins=1000), 'cells'),
])
def test_geometry_beyond_physical_bounds_is_refused_before_anything_is_allocated(kw, match):
    with pytest.raises(GeometryError, match=match):
        geom(**kw)


def test_a_full_turn_and_a_2000_by_2000_sector_are_fine():
    full = geom(angle_min=-math.pi, angle_increment=2 * math.pi / 400, n_beams=401)
    assert full.n_beams == 401
    assert geom(n_beams=2000, angle_increment=1e-3, n_bins=2000).shape == (2000, 2000)


def test_values_rule_refuses_non_echoes_and_accepts_silence():
    g = geom(n_beams=3, n_bins=2)
    assert check_sector(np.zeros((2, 3), np.uint8), g).dtype == np.uint8     # all zero: nothing seen
    for bad, match in ((np.full((2, 3), np.nan), 'NaN'), (np.full((2, 3), -1.0), 'negative'),
                       (np.zeros((2, 3), complex), 'dtype')):
        with pytest.raises(SectorError, match=match):
            check_sector(bad, g)
    assert check_sector(np.full((2, 3), -20.0), g, coding='db').shape == (2, 3)   # dB may be negative
    with pytest.raises(GeometryError, match='geometry says'):
        check_sector(np.zeros((3, 3)), g)
