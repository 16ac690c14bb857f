"""imm_ipda_tracker with ``coverage: scan``: a track that leaves the window of sonar/sector_info ends."""
from __future__ import annotations

import math

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.core.sector import SectorGeometry

pytestmark = pytest.mark.ros


def scan_info(t: float, bearing_min: float, bearing_max: float):
    g = SectorGeometry(angle_min=bearing_min, angle_increment=(bearing_max - bearing_min) / 10, n_beams=11,
                       range_min=10.0, range_max=500.0, n_bins=50)
    return ma.geometry_to_scan(g, stamp_ns=int(round(t * 1e9)), frame_id='sonar')


def detections(t: float, xy) -> object:
    rec = np.zeros(len(xy), ma.DETECTION_DTYPE)
    for i, (x, y) in enumerate(xy):
        rec[i]['x'], rec[i]['y'] = x, y
    rec['cov_xx'] = rec['cov_yy'] = 4.0
    rec['clutter_density'] = 1e-6
    return ma.array_to_cloud(rec, stamp_ns=int(round(t * 1e9)), frame_id='world')


def end_scan(inproc, coverage: str) -> int | None:
    """The scan at which the track of a target seen for 8 scans is gone, the sonar then looking at
    bearings 60-90 deg only (the target at 200 m on bearing 0)."""
    from sonar_tracking.nodes.imm_ipda_tracker import ImmIpdaTrackerNode
    node = inproc(ImmIpdaTrackerNode, coverage=coverage, publish_tentative=True,
                  **{'track.outside_time': 3.0, 'detection.probability': 0.5})   # a slow decay on misses
    subs = {s.topic_name: s for s in node.subscriptions}
    for k in range(30):
        t = float(k)
        away = k >= 8
        window = (math.radians(60), math.radians(90)) if away else (math.radians(-30), math.radians(30))
        subs['/sonar/sector_info'].callback(scan_info(t, *window))
        subs['/detections'].callback(detections(t, [] if away else [(200.0, 0.0)]))
        if k == 7:
            assert node.tracker.report.n_confirmed == 1
        if away and node.tracker.report.n_tracks == 0:
            return k
    return None


def test_a_track_outside_the_scanned_window_ends_after_outside_time(inproc):
    with_window = end_scan(inproc, 'scan')
    without = end_scan(inproc, 'none')
    assert with_window is not None and 8 + 3 <= with_window <= 8 + 4      # outside for track.outside_time
    assert without is None or without > with_window                       # otherwise only existence decays
