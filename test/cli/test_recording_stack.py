"""A recording through the active pipeline: ``sonar_stack recording_active --replay`` brings every scan
to the tracker, because the replay starts only once every node of the stack takes input."""
from __future__ import annotations

import math
import re
import subprocess
import sys

import numpy as np
import pytest

from sonar_tracking import process
from sonar_tracking.core.sector import SectorGeometry

pytestmark = pytest.mark.ros

T0 = 1_715_000_000 * 10**9


def write_recording(path, n: int, period: float, seed: int) -> list[int]:
    """A bag as ``sonar_import`` writes it: ``n`` Micron-like 8-bit sectors (speckle and one bright
    echo) ``period`` seconds apart, sweeping clockwise; returns their stamps [ns]."""
    from sonar_tracking.io.importers import SectorBagWriter
    rng = np.random.default_rng(seed)
    writer = SectorBagWriter(path)
    stamps = []
    for k in range(n):
        geometry = SectorGeometry(angle_min=math.radians(40.0 - 9.0 * k), angle_increment=math.radians(1.8),
                                  n_beams=5, range_min=0.5, range_max=30.0, n_bins=200, ping_period=-period / 5,
                                  scan_time=period)
        counts = rng.integers(0, 40, (geometry.n_bins, geometry.n_beams)).astype(np.uint8)
        counts[120:124, 2] = 220
        stamp = T0 + int(round(k * period * 1e9))
        writer.sector(stamp, stamp, counts, geometry, 'sonar')
        stamps.append(stamp)
    writer.commit()
    return stamps


def header_stamps(bag, topic: str) -> list[int]:
    from sonar_tracking.cli.bag_replay import header_stamp
    from sonar_tracking.io.bags import read_bag
    return [header_stamp(bytes(m.data)) for m in read_bag(bag, [topic])]


def test_every_scan_of_a_recording_reaches_the_tracker(tmp_path):
    stamps = write_recording(tmp_path / 'rec', 20, 0.2, seed=33)
    proc = subprocess.run(
        [sys.executable, '-m', 'sonar_tracking.cli.sonar_stack', 'recording_active', '--preset', 'micron_seaking',
         '--replay', f'{tmp_path / "rec"} --rate 2', '--record', str(tmp_path / 'run')],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=180,
        start_new_session=True, preexec_fn=process.child_dies_with_parent())
    out = proc.stdout
    assert proc.returncode == 0, out
    # The replay started once both nodes had said they take input: the detector learning, the tracker ready.
    assert re.search(r'started bag_replay \(pid \d+\): every node takes input \(active_detector learning, '
                     r'imm_ipda_tracker ready\)', out), out
    assert re.search(r'\[bag_replay\] .*replayed 40 messages', out), out
    # One detections and one tracks message per sector, in order: no scan was lost on the way.
    assert header_stamps(tmp_path / 'run', '/detections') == stamps, out
    assert header_stamps(tmp_path / 'run', '/tracks') == stamps, out
