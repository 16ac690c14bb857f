"""ProjectedSonarImage out of a sector, read back by the importer's reader: the same sector."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.io.importers import ImportOptions, projected_to_sector
from sonar_tracking.io.importers.msgdefs import register_builtin
from sonar_tracking.msgs import sector_to_projected

GEOMETRY = SectorGeometry(angle_min=-math.radians(65), angle_increment=math.radians(130) / 63, n_beams=64,
                          range_min=0.06, range_max=11.94, n_bins=100, ping_period=0.0, scan_time=0.05)


@pytest.mark.parametrize('dtype', [np.uint8, np.uint16, np.float32])
def test_a_sector_survives_the_round_trip(rosbags_types, dtype):
    register_builtin(rosbags_types.typestore)
    values = np.random.default_rng(3).integers(0, 250, GEOMETRY.shape).astype(dtype)
    values[80, 50] = 250                                     # port side: bearing > 0
    msg = sector_to_projected(values, GEOMETRY, 1_700_000_000_000_000_123, 'oculus', rosbags_types,
                              frequency=750e3, beam_width=math.radians(1.0))
    assert msg.header.frame_id == 'oculus' and msg.image.beam_count == 64
    assert msg.beam_directions[50].y < 0                     # the message frame: y starboard
    got, geometry, negatives = projected_to_sector(msg, ImportOptions(), scan_time=0.05)
    assert negatives == 0
    np.testing.assert_array_equal(got, values.astype(got.dtype))
    assert geometry.n_beams == 64 and geometry.n_bins == 100
    assert geometry.angle_min == pytest.approx(GEOMETRY.angle_min, abs=1e-6)
    assert geometry.angle_increment == pytest.approx(GEOMETRY.angle_increment, rel=1e-6)
    assert geometry.range_min == pytest.approx(GEOMETRY.range_min, rel=1e-6)
    assert geometry.range_max == pytest.approx(GEOMETRY.range_max, rel=1e-6)


def test_values_that_do_not_fit_are_refused(rosbags_types):
    register_builtin(rosbags_types.typestore)
    with pytest.raises(ValueError, match='shape'):
        sector_to_projected(np.zeros((3, 3), np.uint8), GEOMETRY, 1, 'x', rosbags_types)
    with pytest.raises(ValueError, match='cannot carry'):
        sector_to_projected(np.zeros(GEOMETRY.shape, np.complex64), GEOMETRY, 1, 'x', rosbags_types)
