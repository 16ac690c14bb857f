"""Intensity decoding and range gating (core/intensity.py)."""
import numpy as np
import pytest

from sonar_tracking.core.config import ConfigError
from sonar_tracking.core.intensity import IntensityConfig, condition, decode, full_scale_of, gate_ranges
from sonar_tracking.core.sector import SectorGeometry


def test_db_counts_decode_to_amplitude_with_the_span_over_the_full_count_range():
    counts = np.array([0, 1, 52, 255], np.uint8)
    a = decode(counts, 'db', db_span=51.0, full_scale=full_scale_of(counts.dtype))
    # 51 dB over 255 counts: 0.2 dB per count, relative to count 1; zero stays no echo
    assert a[0] == 0.0
    assert a[1] == pytest.approx(1.0)
    assert 20 * np.log10(a[2]) == pytest.approx(51 * 0.2)
    assert 20 * np.log10(a[3]) == pytest.approx(254 * 0.2)


def test_float_db_values_are_decibels_and_power_and_display_codings():
    assert decode(np.array([20.0, 0.0, -20.0]), 'db') == pytest.approx([10.0, 1.0, 0.1])   # float dB: 0 dB is a level
    assert decode(np.array([4.0, 0.0]), 'linear_power').tolist() == [2.0, 0.0]
    d = decode(np.array([0, 255, 128], np.uint8), 'display', gamma=2.0, full_scale=255.0)
    assert d.tolist() == pytest.approx([0.0, 1.0, (128 / 255) ** 2])
    with pytest.raises(ValueError, match='unknown intensity coding'):
        decode(np.zeros(2), 'log')


def test_condition_blanks_the_near_field_cuts_at_max_range_and_floors_noise():
    geom = SectorGeometry(angle_min=-0.5, angle_increment=0.1, n_beams=11, range_min=0.5, range_max=50.0,
                          n_bins=100)
    values = np.full(geom.shape, 3.0)
    values[10] = 0.5
    cfg = IntensityConfig(blank_range=2.0, max_range=30.0, noise_floor=1.0)
    out, g = condition(values, geom, cfg)
    first, stop = gate_ranges(geom, 2.0, 30.0)
    assert g.n_bins == stop == out.shape[0] and g.range_max <= 30.0 < g.range_max + geom.range_resolution
    assert np.all(out[:first] == 0) and geom.ranges()[first] >= 2.0 > geom.ranges()[first - 1]
    assert np.all(out[10] == 0) and np.all(out[first:10] == 3.0)
    assert values[0, 0] == 3.0  # input untouched


def test_a_max_range_inside_the_blanked_zone_is_refused():
    with pytest.raises(ConfigError, match='max_range'):
        IntensityConfig(blank_range=5.0, max_range=3.0)
