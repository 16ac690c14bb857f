"""The imaging-sonar study: the preset read as the nodes read it, reduced frames, the Poisson bound,
and a seeded reduced run of every part of ``sonar_eval imaging``."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from sonar_tracking.core.detection.cfar import Cfar
from sonar_tracking.studies import imaging_table
from sonar_tracking.studies.evidence import SeedSplit
from sonar_tracking.studies.imaging_study import ImagingRun, front_end, poisson_upper, region_front_end, run_once


def test_the_front_end_is_the_preset_file_and_reduced_frames_divide_the_cell_counts():
    full, trk = front_end('oculus_m750d')
    half, _ = front_end('oculus_m750d', 2)
    assert full.threshold.method == 'ca' and full.intensity.coding == 'db'
    assert (trk.existence.confirm_distance, trk.existence.confirm_lapse, full.cells.target_size) == (2.5, 0.9, 1.8)
    assert (full.cfar.stride_beams, full.cfar.reach_beams) == (4, 24)
    assert (half.cfar.stride_beams, half.cfar.reach_beams, half.cells.merge_bins) == (2, 12, 5)
    # The training reach still passes the guard by a stride, so CFAR has training cells.
    for cfg in (full, half, front_end('aris3000', 4)[0]):
        c = cfg.cfar
        assert c.reach_bins >= c.guard_bins + c.stride_bins and c.reach_beams >= c.guard_beams + c.stride_beams
        assert Cfar(cfg.threshold.method, c).training_cells > 0


def test_the_region_path_is_the_presets_fls_section_with_windows_kept_odd_on_reduced_frames():
    full = region_front_end('oculus_m750d')
    half = region_front_end('oculus_m750d', 2, {'segment.seed_db': 3.0})
    assert full.intensity.coding == 'db' and full.segment.seed_db == 6.0 and half.segment.seed_db == 3.0
    assert (full.filter.window_bins, full.filter.window_beams, full.filter.background_bins) == (5, 3, 81)
    assert (half.filter.window_bins, half.filter.window_beams, half.filter.background_bins) == (3, 1, 41)
    assert half.segment.min_cells == full.segment.min_cells / 4


def test_poisson_upper_bound():
    assert poisson_upper(0, 3.0) == pytest.approx(2.9957 / 3.0, rel=1e-4)   # -ln(0.05) events in 3 h
    assert poisson_upper(2, 10.0) == pytest.approx(6.2958 / 10.0, rel=1e-4)
    assert poisson_upper(0, 0.0) == math.inf


def test_a_run_is_reproducible_and_the_trackers_share_its_detections():
    run = ImagingRun('imaging_school', scale=4, frames=30, methods=('ipda', 'jipda'), confirm=(('jipda', 0.95),))
    a = run_once(run, np.random.SeedSequence(7))
    b = run_once(run, np.random.SeedSequence(7))
    assert a['ipda'] == b['ipda'] and a['detector'] == b['detector']
    assert a['ipda']['confirm'] == 0.99 and a['jipda']['confirm'] == 0.95


@pytest.mark.slow
def test_every_part_runs_reduced_and_shows_what_it_measures(monkeypatch):
    """ESC brings the density back after the clutter turns K while CA alone stays far above it; the
    static scene confirms nothing; a lower design P_fa gives fewer false detections."""
    monkeypatch.setattr(imaging_table, 'ESC_SWITCH', 100)
    monkeypatch.setattr(imaging_table, 'ESC_SCORED', (400, 500))
    monkeypatch.setattr(imaging_table, 'PFA_GRID', (1e-3, 1e-6))
    monkeypatch.setattr(imaging_table, 'CFAR_METHODS', ('ca',))
    monkeypatch.setattr(imaging_table, 'SEED_DB_GRID', (3.0,))
    monkeypatch.setattr(imaging_table, 'RHO_FACTORS', (1.0,))
    monkeypatch.setattr(imaging_table, 'T_GRID', (0.99,))
    sizes = imaging_table.Sizes(runs=2, calibration_runs=1, roc_runs=3, esc_runs=2, static_frames=300,
                                diver_frames=200, school_frames=100, scale=4, static_scale=4, esc_frames=500)
    result = imaging_table.run_table(SeedSplit((11,), (21, 22)), sizes)
    json.dumps(result, default=lambda o: o.tolist())
    esc = result['esc']['sets']
    for s in ('21', '22'):
        on, off = esc[s]['esc_on']['after']['mean'], esc[s]['esc_off']['after']['mean']
        assert off > 4.0, 'CA-CFAR alone under K clutter exceeds its design density several times'
        assert on < 0.5 * off
    assert all(v['confirmed_tracks'] == 0 for v in result['static']['sets'].values())
    rows = {row['pfa']: row for row in result['roc']['rows'] if row['method'] == 'ca'}
    assert rows[1e-3]['false_per_frame']['mean'] > 10 * rows[1e-6]['false_per_frame']['mean']
    regions = [row for row in result['roc']['rows'] if row['method'] == 'regions']
    assert [row['seed_db'] for row in regions] == [3.0] and regions[0]['runs'] == 3
    assert result['diver']['read_back']['equal']
    text = imaging_table.format_table(json.loads(json.dumps(result, default=lambda o: o.tolist())))
    for heading in ('**Detection**', '**ESC under a change of clutter shape**', '**Static empty scene',
                    '**Diver**', '**Crossing school**'):
        assert heading in text


def test_another_head_runs_with_its_own_preset_and_frame_rate(monkeypatch):
    from sonar_tracking.studies import imaging_table
    monkeypatch.setattr(imaging_table, 'RHO_FACTORS', (1.0,))
    sizes = imaging_table.Sizes(runs=1, calibration_runs=1, static_frames=150, diver_frames=60, scale=2,
                                static_scale=2, sensor='aris3000')
    result = imaging_table.run_table(SeedSplit((11,), (21, 22)), sizes, parts=('static', 'diver'))
    assert result['sensor'] == 'aris3000'
    assert all(v['minutes'] == pytest.approx(150 / 15.0 / 60.0) for v in result['static']['sets'].values())
    assert result['diver']['read_back']['equal']
    assert imaging_table.format_table(result).startswith('Head aris3000.')
    assert result['diver']['rho_d'] == pytest.approx(1e-2), "the ARIS preset's own rho_D, not the Oculus's"


def test_the_diver_grid_is_a_factor_of_each_presets_density():
    from sonar_tracking.studies import imaging_table
    assert imaging_table.rho_grid('oculus_m750d') == pytest.approx((2e-4, 5e-4, 2e-3))
    assert imaging_table.rho_grid('aris3000') == pytest.approx((4e-3, 1e-2, 4e-2))


@pytest.mark.parametrize('argv', [['--parts', 'roc,foo'], ['--parts', 'esc,esc'], ['--seeds', '501,601'],
                                  ['--seeds', '601,602', '--scale', '0'],
                                  ['--sensor', 'aris3000', '--parts', 'diver,school']])
def test_sonar_eval_imaging_refuses_bad_arguments_before_running(argv, capsys):
    from sonar_tracking.cli import sonar_eval
    assert sonar_eval.main(['imaging', *argv]) == 2
    assert 'error:' in capsys.readouterr().err


def test_a_part_run_on_other_seeds_names_them_in_its_heading():
    from sonar_tracking.studies import imaging_table
    seeds = {'calibration': [501], 'evaluation': [601, 602], 'tuned_on': [1]}
    row = {'minutes': 10.0, 'confirmed_tracks': 0, 'false_per_frame': 0.3}
    static = {'scale': 1, 'frames': 10, 'sets': {'603': row}}
    result = {'seeds': seeds, 'gospa': {'c': 3.0, 'p': 2.0, 'alpha': 2.0}, 'gate': 1.5, 'clearance': 3.0,
              'static': {**static, 'seeds': {**seeds, 'evaluation': [603, 604], 'tuned_on': [1, 3]}}}
    assert 'evaluation seeds 603 / 604' in imaging_table.format_table(result)
    result['static'] = {**static, 'seeds': {**seeds, 'tuned_on': [1, 3]}}
    assert '603 / 604' not in imaging_table.format_table(result)
