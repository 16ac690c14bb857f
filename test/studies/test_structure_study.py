"""Counting tracks on static structure: the classification on a constructed case, the structure
distance on the tank layout, and a short run whose counts add up."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sonar_tracking.core.records import GPF_TRACK_DTYPE
from sonar_tracking.sim.structure import StructureConfig, build_structure
from sonar_tracking.studies.structure_study import count_structure_tracks, run_structure_study, structure_distance


def frame(*tracks):
    """Records of ``(track_id, x, y, confirmed)``."""
    rec = np.zeros(len(tracks), GPF_TRACK_DTYPE)
    for k, (tid, x, y, confirmed) in enumerate(tracks):
        rec[k]['track_id'], rec[k]['x'], rec[k]['y'], rec[k]['confirmed'] = tid, x, y, confirmed
    return rec


def test_count_structure_tracks_on_a_constructed_case():
    # Structure: everything at x >= 100 (a wall); one target moving along y = 0 from x = 0 to 20.
    def distance(k, xy):
        return np.maximum(0.0, 100.0 - xy[:, 0])

    truths = [np.array([[0.0, 0.0, 10.0, 0.0]]), np.array([[10.0, 0.0, 10.0, 0.0]]),
              np.array([[20.0, 0.0, 10.0, 0.0]])]
    records = [
        frame((1, 0.5, 0.0, 1), (2, 101.0, 5.0, 1), (3, 50.0, 50.0, 1), (4, 105.0, 0.0, 0), (5, 100.5, 9.0, 1),
              (6, 102.0, 0.0, 1)),
        frame((1, 10.0, 1.0, 1), (2, 101.0, 5.0, 1), (5, 80.0, 9.0, 1), (6, 12.0, 0.0, 1)),
        frame((2, 100.8, 5.2, 1), (7, 20.0, 3.0, 0)),
    ]
    c = count_structure_tracks(records, truths, distance, near=2.0, clearance=5.0, gate=2.0)
    assert c.frames == 3
    assert c.confirmed_tracks == 5                       # 1, 2, 3, 5, 6 (4 and 7 never confirmed)
    assert c.on_target == 2                              # 1, and 6 which passed near the target once
    assert c.structure_track_ids == (2,)                 # 5 left the structure, 3 never on it
    assert c.on_structure == 1 and c.elsewhere == 2      # 3 and 5
    # Target tracked in frames 0 (track 1 at 0.5 m) and 1 (track 1 at 1 m); frame 2: only an
    # unconfirmed track near it.
    assert c.cttr == pytest.approx(2 / 3)
    assert c.cle == pytest.approx(0.75)


def test_count_structure_tracks_without_targets_or_tracks():
    c = count_structure_tracks([frame(), frame((3, 1.0, 1.0, 1))], [np.zeros((0, 4))] * 2,
                               lambda k, xy: np.zeros(len(xy)), 1.0, 2.0, 1.5)
    assert c.confirmed_tracks == 1 and c.on_structure == 1 and math.isnan(c.cttr) and math.isnan(c.cle)
    with pytest.raises(ValueError):
        count_structure_tracks([frame()], [], lambda k, xy: xy[:, 0], 1.0, 2.0, 1.5)


def test_structure_distance_in_the_tank():
    st = build_structure(StructureConfig(kind='tank'), np.random.default_rng(0))
    pts = np.array([[28.5, 0.0], [15.0, 0.0], [0.0, 4.5], [0.8, 0.0], [20.0, 7.9]])
    d = structure_distance(pts, st, (0.0, 0.0))
    assert d[0] < 0.15                                  # on the back wall (0.2 m thick, 0.1 m spacing)
    assert d[1] == pytest.approx(8.0, abs=0.15)         # open water: the side walls are 8 m away
    assert d[2] == 0.0                                  # in the seabed band (3-6 m)
    assert d[3] == 0.0                                  # in the ringdown (to 1.38 m)
    assert d[4] < 0.2


def test_a_short_structured_run_adds_up():
    c = run_structure_study('structure_only', 3, 3, 'seaking675')
    assert c.frames >= 2
    assert c.on_target == 0 and math.isnan(c.cttr)      # no target in the scene
    assert c.on_target + c.on_structure + c.elsewhere == c.confirmed_tracks
    plain = run_structure_study('fls1', 3, 2)           # a plain twin: its tracks are on nothing static
    assert plain.on_structure == 0 and plain.frames >= 1


def test_runs_combine_by_sums_and_frame_weighted_rates():
    from sonar_tracking.studies.structure_study import StructureCounts, combine
    a = StructureCounts(frames=10, confirmed_tracks=2, on_target=1, on_structure=1, elsewhere=0,
                        structure_track_ids=(5,), cttr=0.5, cle=1.0)
    b = StructureCounts(frames=30, confirmed_tracks=1, on_target=1, on_structure=0, elsewhere=0,
                        structure_track_ids=(), cttr=1.0, cle=2.0)
    c = combine([a, b])
    assert (c.frames, c.confirmed_tracks, c.on_target, c.on_structure) == (40, 3, 2, 1)
    assert c.cttr == pytest.approx(35 / 40) and c.cle == pytest.approx((5 * 1.0 + 30 * 2.0) / 35)
