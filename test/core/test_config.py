"""Declared configuration: bounds, types, flattening, unknown names."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import pytest

from sonar_tracking.core.config import Config, ConfigError, setting


@dataclass(frozen=True)
class Inner(Config):
    gain: float = setting(0.5, 'loop gain', low=0.0, high=1.0, high_open=True)
    mode: str = setting('a', 'mode', choices=('a', 'b'))


@dataclass(frozen=True)
class Outer(Config):
    count: int = setting(3, 'how many', low=1)
    enabled: bool = setting(True, 'on/off')
    limits: tuple[float, ...] = setting((1.0, 2.0), 'bounds', low=0.0)
    inner: Inner = dataclasses.field(default_factory=Inner)

    def validate(self):
        if len(self.limits) != 2 or self.limits[0] >= self.limits[1]:
            raise ConfigError(f'limits = {self.limits} must be two increasing values')


def test_defaults_and_flat_names():
    c = Outer()
    assert c.flat() == {'count': 3, 'enabled': True, 'limits': (1.0, 2.0), 'inner.gain': 0.5, 'inner.mode': 'a'}
    names = [s.name for s in Outer.settings()]
    assert names == ['count', 'enabled', 'limits', 'inner.gain', 'inner.mode']


@pytest.mark.parametrize('values, match', [
    ({'count': 0}, 'count = 0 must be >= 1'),
    ({'count': 2.5}, 'must be of type int'),
    ({'enabled': 1}, 'must be of type bool'),
    ({'inner.gain': 1.0}, 'inner.gain = 1.0 must be < 1.0'),
    ({'inner.gain': float('nan')}, 'must be finite'),
    ({'inner.mode': 'c'}, "not one of \\['a', 'b'\\]"),
    ({'limits': (2.0, 1.0)}, 'two increasing'),
    ({'limits': (-1.0, 1.0)}, 'must be >= 0.0'),
    ({'inner.gian': 0.1}, 'unknown setting'),
])
def test_invalid_values_name_the_setting(values, match):
    with pytest.raises(ConfigError, match=match):
        Outer.from_flat(values)


def test_from_flat_changes_only_given_names_and_coerces_ints_to_float():
    c = Outer.from_flat({'inner.gain': 0, 'count': 7})
    assert c.inner.gain == 0.0 and isinstance(c.inner.gain, float)
    assert c.count == 7 and c.inner.mode == 'a'
    d = Outer.from_flat({'inner.mode': 'b'}, base=c)
    assert d.count == 7 and d.inner.mode == 'b'


def test_bounds_text():
    s = {s.name: s for s in Outer.settings()}
    assert s['inner.gain'].bounds_text() == '[0, 1)'
    assert s['count'].bounds_text() == '[1, inf)'
    assert s['inner.mode'].bounds_text() == 'one of a, b'


def test_array_parameters_from_rclpy_are_accepted():
    """rclpy hands a double-array parameter set at run time over as array.array('d')."""
    import array
    c = Outer.from_flat({'limits': array.array('d', [0.5, 3.0])})
    assert c.limits == (0.5, 3.0)
