"""Acceptance (issue 8): on 100 seeded SeaKing 675 kHz frames of the FLS Table 5 situations, with
default parameters, at least 95% of the targets of 10 dB or more are found, at most one false
region per frame on average, and the modified filter and region growing beat the plain median blur
and threshold + connected components on both counts.

The defaults were chosen on other seeds (2000-2199); these frames (seeds 8001-8014) were not used
for tuning.
"""
from __future__ import annotations

import numpy as np
import pytest

from sonar_tracking.core.fls import FlsConfig
from sonar_tracking.studies.fls_segmentation import PlainConfig, score_frames, simulate_frames

SEED = 8000


@pytest.fixture(scope='module')
def frames():
    out = []
    for n in range(1, 15):
        # Every other sweep from the second on: 6 to 8 frames per situation, 100 in all, spread
        # over each situation (targets from 25 m in to 6 m, crossing, side by side).
        out += list(simulate_frames(f'fls{n}', SEED + n, first=1, every=2))
    return out


def test_default_pipeline_meets_the_acceptance_figures(frames):
    assert len(frames) == 100
    s = score_frames(frames, min_snr_db=10.0)
    print(f'\nmodified: {s.as_dict()} missed {s.missed}')
    assert s.targets >= 80, 'too few targets of 10 dB or more to measure a 95% rate'
    assert s.detection_rate >= 0.95
    assert s.false_per_frame <= 1.0


def test_modified_filters_beat_the_plain_ones(frames):
    mod = score_frames(frames)
    # The plain pipeline with the same window (3 x 3), threshold (the seed level) and a minimum size.
    plain = score_frames(frames, plain=PlainConfig(ksize=3, threshold_db=5.5, min_pixels=4))
    print(f'\nplain 3x3 at 5.5 dB: {plain.as_dict()}')
    assert mod.detection_rate > plain.detection_rate
    assert mod.false_per_frame < plain.false_per_frame
    # Fragments: more targets found by the modified pipeline, yet no more extra regions on them.
    assert mod.duplicates_per_frame <= plain.duplicates_per_frame


@pytest.mark.parametrize('ksize', [3, 5])
def test_no_plain_threshold_does_as_well_on_both_counts(frames, ksize):
    """Not a matter of the plain threshold: at every threshold the plain pipeline finds fewer
    targets or makes more false regions (usually both) than the default modified one."""
    mod = score_frames(frames)
    for thr in np.arange(2.0, 10.01, 1.0):
        plain = score_frames(frames, plain=PlainConfig(ksize=ksize, threshold_db=float(thr), min_pixels=4))
        print(f'plain {ksize}x{ksize} {thr:4.1f} dB: detection {plain.detection_rate:.3f}, '
              f'false/frame {plain.false_per_frame:.2f}')
        assert plain.detection_rate < mod.detection_rate or plain.false_per_frame > mod.false_per_frame


def test_fragments_of_strong_targets_are_joined():
    """At high SNR the faces, corners and surface echo of a tank target can come apart in the image
    (paper §2, drawbacks 2-3); joining keeps one region per target where unjoined growth and plain
    components split some of them."""
    def run(config=None):
        return [lf for n in (1, 2, 3, 4, 12)
                for lf in simulate_frames(f'fls{n}', SEED + 50 + n, config, first=1, every=2, snr_db=35.0)]
    frames = run()
    joined = score_frames(frames)
    apart = score_frames(run(FlsConfig.from_flat({'segment.join_distance': 0.0})))
    plain = score_frames(frames, plain=PlainConfig(ksize=3, threshold_db=5.5, min_pixels=4))
    print(f'\n{len(frames)} frames at 35 dB, extra regions on targets: joined {joined.duplicates}, '
          f'unjoined {apart.duplicates}, plain {plain.duplicates}')
    assert joined.detection_rate == 1.0 and apart.detection_rate == 1.0
    assert joined.duplicates == 0 < apart.duplicates
    assert joined.duplicates <= plain.duplicates
