"""The JIPDA study: simulation geometry, the per-run scores, determinism."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.records import TRACK_DTYPE
from sonar_tracking.studies.jipda_study import JipdaStudy, _score, run_once, simulate, summarise


@pytest.mark.parametrize('geometry', ['crossing', 'parallel'])
def test_simulated_geometry(geometry):
    study = JipdaStudy(geometry=geometry, scans=41)
    truth, scans, param = simulate(study, np.random.default_rng(4))
    assert truth.shape == (41, 2, 4) and len(scans) == 41
    speeds = np.hypot(truth[..., 2], truth[..., 3])
    np.testing.assert_allclose(speeds, study.speed)
    gap = np.hypot(*(truth[:, 0, :2] - truth[:, 1, :2]).T)
    if geometry == 'crossing':
        assert 5.0 <= param <= 20.0 and gap[20] == pytest.approx(0.0, abs=1e-9)
        heading = np.degrees(np.arctan2(truth[0, :, 3], truth[0, :, 2]))
        assert abs((heading[0] - heading[1] + 180) % 360 - 180) == pytest.approx(param)
    else:
        assert 2.0 <= param <= 4.0
        np.testing.assert_allclose(gap, param * study.cell)
    assert study.cell == pytest.approx(math.sqrt(12 * 5.0 * 2500 * math.radians(0.1)))
    for z, R in scans:
        assert z.shape[1] == 2 and R.shape == (len(z), 2, 2) and np.all(np.linalg.eigvalsh(R) > 0)


def tracks(*rows):
    out = np.zeros(len(rows), TRACK_DTYPE)
    for i, (tid, x, y) in enumerate(rows):
        out[i]['track_id'], out[i]['x'], out[i]['y'], out[i]['confirmed'] = tid, x, y, 1
    return out


def test_scores_count_a_swap_and_coalescence():
    study = JipdaStudy(scans=4)
    truth = np.zeros((4, 2, 4))
    truth[:, 0, :2], truth[:, 1, :2] = (0.0, 0.0), (0.0, 50.0)
    outputs = [tracks((1, 0, 0), (2, 0, 50)), tracks((1, 0, 50), (2, 0, 0)),     # swap: both targets
               tracks((1, 0, 48), (2, 0, 45)),                                   # two tracks on target 1
               tracks((3, 0, 1))]                                                # a new track, no swap
    s = _score(study, truth, outputs, np.eye(4))
    assert s['swaps'] == 2.0 and s['coalescence'] == pytest.approx(1 / 4)
    assert s['gospa'] > 0 and 0 <= s['cttr'] <= 1


def test_run_is_a_function_of_its_seed_and_summary_shape():
    study = JipdaStudy(geometry='parallel', scans=15)
    seeds = np.random.SeedSequence(3).spawn(2)
    a, b = run_once(study, seeds[0]), run_once(study, seeds[0])
    assert a == b and a != run_once(study, seeds[1])
    s = summarise([a, run_once(study, seeds[1])])
    assert set(s['means']) == {'ipda', 'jipda'} and s['jipda_minus_ipda']['gospa']['runs'] == 2


def test_unresolved_targets_give_one_detection():
    study = JipdaStudy(geometry='crossing', scans=21, p_detect=1.0, clutter_density=1e-12, unresolved=True)
    truth, scans, _ = simulate(study, np.random.default_rng(1))
    gap = np.hypot(*(truth[:, 0, :2] - truth[:, 1, :2]).T)
    counts = np.array([len(z) for z, _ in scans])
    assert counts[10] == 1 and np.all(counts[gap > 2 * study.cell] == 2)
