"""make demo: the harbour pipeline through real nodes, a bag, a summary and a PNG of tracks on truth."""
from __future__ import annotations

import re
import subprocess
import sys

import pytest
import yaml

pytestmark = pytest.mark.ros


def test_demo_runs_the_pipeline_and_shows_tracks_on_truth(tmp_path):
    r = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.demo', '--out', str(tmp_path)],
                       capture_output=True, text=True, timeout=150)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    out = r.stdout
    assert re.search(r'100 scans in [\d.]+ s', out)
    from sonar_tracking.cli.sonar_stack import _has_view
    if _has_view():     # make test installs the view extra: the demo prints where to watch it
        assert re.search(r'^view: http://127\.0\.0\.1:\d+\S*$', out, re.M), out[:2000]
    else:
        assert 'no live view' in out
    true_tracks = int(re.search(r'true \(eqs\. 47-48\)\s+(\d+)', out).group(1))
    assert true_tracks >= 1
    png = tmp_path / 'demo_harbour.png'
    assert png.stat().st_size > 20_000 and str(png.resolve()) in out
    meta = yaml.safe_load((tmp_path / 'demo_bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    counts = {t['topic_metadata']['name']: t['message_count'] for t in meta['topics_with_message_count']}
    assert counts['/sonar/sector'] == counts['/tracks'] == counts['/detections'] == 100
