"""The view in a browser: the shipped stacks started with ``sonar_stack STACK --view`` as shipped, Debian's
headless Chromium (software WebGL, no GPU) loading the page while they run. The run is read back from
the page itself (the recording its viewer holds, and its layout) and from the ``.rrd`` the view saved,
and each page is screenshot into out/test_view_browser/. One browser serves the three stacks."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sonar_tracking import process

OUT = Path(__file__).resolve().parents[2] / 'out' / 'test_view_browser'
WIDTH, HEIGHT = 1600, 1000

# The view's file is read while it is written (no footer yet): Rerun warns and scans it whole.
# One worker runs the three stacks in turn, with one browser (pytest -n: --dist loadgroup).
pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.filterwarnings('ignore:RRD file has no footer'),
              pytest.mark.xdist_group('browser')]


@pytest.fixture(scope='module')
def browser():
    from sonar_tracking.cli.view.browser import Chromium, find_chromium
    if find_chromium() is None:
        if os.environ.get('SONAR_VIEW_BROWSER_REQUIRED'):  # CI: a missing browser is a failure, not a skip
            pytest.fail("Debian's chromium is not installed (`make view-deps` installs it)")
        pytest.skip("Debian's chromium is not installed (`make view-deps` installs it)")
    pytest.importorskip('rerun')  # the view extra (`make view-deps` installs it)
    OUT.mkdir(parents=True, exist_ok=True)
    with Chromium(WIDTH, HEIGHT) as b:
        yield b


def wait_for(what: str, predicate, timeout: float, poll: float = 0.25):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        got = predicate()
        if got:
            return got
        time.sleep(poll)
    raise AssertionError(f'waited {timeout:g} s for {what}')


class Stack:
    """``sonar_stack NAME --view "--save FILE"`` (plus ``--set`` settings), its output in out/."""

    def __init__(self, name: str, rrd: Path, settings: tuple[str, ...] = ()) -> None:
        self.log = OUT / f'{name}.log'
        self.proc = subprocess.Popen(
            [sys.executable, '-m', 'sonar_tracking.cli.sonar_stack', name, *settings, '--view', f'--save {rrd}'],
            stdout=self.log.open('w'), stderr=subprocess.STDOUT, start_new_session=True,
            preexec_fn=process.child_dies_with_parent())

    def line(self, pattern: str, timeout: float = 180.0) -> re.Match:
        def found():
            m = re.search(pattern, self.log.read_text())
            if m is None and self.proc.poll() is not None:
                raise AssertionError(f'the stack exited before {pattern!r}:\n{self.log.read_text()[-3000:]}')
            return m
        return wait_for(f'{pattern!r} in {self.log}', found, timeout)

    def stop(self) -> int:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            self.proc.wait(60)
        return self.proc.returncode


def run_in_browser(browser, name: str, tmp_path: Path, entity: str, settings: tuple[str, ...] = ()):
    """Run a stack with its view loaded in the browser until the page holds the whole run; returns
    (the page's columns, its panel names, the saved file's columns and panel names, scans, the screenshot)."""
    from sonar_tracking.cli.view.browser import latest_log_time, panel_names, rrd_columns
    rrd = tmp_path / f'{name}.rrd'
    stack = Stack(name, rrd, settings)
    try:
        url = stack.line(r'\[sonar_view\] view: (\S+)').group(1)
        browser.open(url)  # while the pipeline starts
        finished = stack.line(r'\[seaking_sim\] \[INFO\] \[(\d+\.\d+)\] \[seaking_sim\]: .* finished after (\d+) '
                              r'sectors')
        scans = int(finished.group(2))
        # V1: the pipeline is over, the view stays and keeps the run for the browser.
        stack.line('sonar_view keeps the whole run')
        assert stack.proc.poll() is None

        def counts(columns: dict) -> dict:
            # Rows on the timeline: the page keeps only the last of an entity's static rows, the file each.
            return {(e, c): sum(t is not None for t, _ in rows) for e, cs in columns.items() for c, rows in cs.items()}

        seen: dict = {}

        def caught_up():
            # Cheap to ask (the viewer's state, the file's size): the view's file unchanged for 2 s (it may
            # still drain its queue after the pipeline ends) and the page holding its newest row.
            if not rrd.exists():
                return False
            size = rrd.stat().st_size
            if seen.get('size') != size:
                seen.update(size=size, since=time.monotonic(), last=None)
            if time.monotonic() - seen['since'] < 2.0:
                return False
            if seen['last'] is None:
                seen['last'] = latest_log_time(rrd)
            newest = browser.newest_log_time()
            return seen['last'] is not None and newest is not None and newest >= seen['last']

        def whole_run():
            # Everything the view logged is in the page: every column of its file at least as many timed rows.
            data = browser.recording()
            if data is None:
                return None
            try:
                cols, logged = rrd_columns(data), rrd_columns(rrd)
            except ValueError:      # no recording store in it yet: the page (or the file) is still empty
                return None
            page, file = counts(cols), counts(logged)
            seen['differ'] = {k: (page.get(k, 0), n) for k, n in file.items() if page.get(k, 0) < n}
            return (cols, data) if cols.get(entity, {}).get('Points2D:positions') and not seen['differ'] else None
        try:
            wait_for("the page to hold the view's newest row", caught_up, 200.0, poll=0.5)
            cols, data = wait_for(f'the page to hold every row the view logged, {entity} among them', whole_run,
                                  30.0, poll=1.0)
        except AssertionError as e:
            raise AssertionError(f'{e}; rows (page, file) where the page has fewer: {seen.get("differ")}') from None
        lag = time.time() - float(finished.group(1))
        print(f'{name}: the page held the whole run {lag:.1f} s after the last sector; its newest row was '
              f'logged {latest_log_time(data) - float(finished.group(1)):.1f} s after it')
        layout = wait_for('the page layout', browser.layout, 30.0)
        time.sleep(2.0)  # let the last frame render before the screenshot
        shot = browser.screenshot()
        (OUT / f'{name}.png').write_bytes(shot)
    finally:
        code = stack.stop()
    assert code == 0, stack.log.read_text()[-3000:]
    return cols, panel_names(layout), rrd_columns(rrd), panel_names(rrd), scans, shot


def colour_pixels(png: bytes, rgb: tuple[int, int, int], box: tuple[int, int, int, int], tol: int = 40) -> int:
    """Pixels of ``png`` within ``tol`` of colour ``rgb`` inside ``box = (x0, y0, x1, y1)``."""
    import cv2
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)[box[1]:box[3], box[0]:box[2], ::-1]
    return int((np.abs(img.astype(int) - np.array(rgb)).max(axis=2) <= tol).sum())


MAP = (0, 40, 780, 800)        # the map in a 1600 x 1000 page
LEGEND = (0, 800, 780, 960)
RIGHT = (780, 40, 1300, 960)   # polar data and plots, left of the selection panel


def times(cols: dict, entity: str) -> list[int]:
    return [t for t, _ in cols[entity]['Points2D:positions']]


def test_the_harbour_stack_shows_its_whole_run_with_panels_legend_and_details(browser, tmp_path):
    from sonar_tracking.cli.view.scene import PANELS
    # --view runs the simulator in real time: 30 scans of the scenario, 30 s.
    page, names, saved, saved_names, scans, shot = run_in_browser(browser, 'harbour', tmp_path,
                                                                  '/map/tracks/confirmed/points',
                                                                  ('--set', 'seaking_sim.duration=30'))
    # The whole run, in the page and in the file: one row of tracks and of truth per scan, on a
    # timeline of seconds since the start (scan k at k seconds; not 1970).
    whole = [k * 10**9 for k in range(scans)]
    for cols in (page, saved):
        assert times(cols, '/map/tracks/confirmed/points') == whole
        assert times(cols, '/map/truth/points') == whole
    confirmed = [(t, v) for t, v in page['/map/tracks/confirmed/points']['Points2D:labels'] if v]
    assert len(confirmed) > scans // 2 and confirmed[-1][0] == whole[-1]  # the target is tracked to the end
    # Per-track details for the selection panel: existence and IMM mode probabilities.
    details = page['/map/tracks/confirmed/points']
    existence = [e for _, v in details['existence'] if v for e in v]
    modes = np.array([[x for _, v in details[m] if v for x in v] for m in ('mode_cv', 'mode_ccw', 'mode_cw')])
    assert len(existence) >= len(confirmed) and all(0.0 <= e <= 1.0 for e in existence)
    assert modes.shape[1] == len(existence) and np.allclose(modes.sum(axis=0), 1.0, atol=1e-6)
    # V3/V4: one layout for this stack, named panels, in the page and in the file.
    assert set(names) == set(saved_names) == set(PANELS.values())
    for entity in ('/sector/polar', '/map/grid', '/map/scale', '/legend'):
        assert entity in page, entity
    # What the screenshot shows: the fan (dark pixels) and detections (orange) on the map, the
    # track (green), the legend's coloured names, the polar data and the threshold curve on the right.
    missing = [what for what, colour, box, n in (
        ('the fan', (10, 10, 10), MAP, 50_000), ('detections', (255, 160, 0), MAP, 50),
        ('the track', (40, 220, 60), MAP, 20), ('the legend', (40, 220, 60), LEGEND, 20),
        ('the threshold curve', (230, 60, 60), RIGHT, 50)) if colour_pixels(shot, colour, box) < n]
    assert not missing, f'not drawn: {missing} (see {OUT / "harbour.png"})'


def test_the_fls_stack_has_its_own_layout_and_region_ids_leave_track_ids_visible(browser, tmp_path):
    from sonar_tracking.cli.view.scene import PANELS
    # At full speed (the stack file's rate, over --view's real time): the page catches up after the run.
    page, names, saved, saved_names, scans, shot = run_in_browser(browser, 'fls', tmp_path,
                                                                  '/map/gpf/confirmed/points',
                                                                  ('--set', 'seaking_sim.rate=0'))
    # No ESC panels for a stack without the ESC detector.
    assert set(names) == set(saved_names) == {PANELS[k] for k in ('map', 'legend', 'polar', 'confirmed', 'counts')}
    assert times(page, '/map/truth/points') == times(saved, '/map/truth/points')
    # The truth of (nearly) every sector: fls8's five sectors 0.05 s after the one before (the sweep
    # turning) fall within sonar_view's --record-period (0.2 s) and are left out.
    truth = times(page, '/map/truth/points')
    assert len(truth) >= scans - 2 - 5 and min(np.diff(truth)) >= 0.2e9
    assert times(page, '/map/gpf/confirmed/points') == times(saved, '/map/gpf/confirmed/points')
    gpf = page['/map/gpf/confirmed/points']
    labelled = [v for _, v in gpf['Points2D:labels'] if v]
    assert labelled and all(t.startswith('T') for v in labelled for t in v)
    assert {f for _, v in gpf['fusion'] if v for f in v} <= {'MF (multiplicative)', 'WF (weighted sum)'}
    assert all(v == [False] for _, v in page['/map/regions']['Points2D:show_labels'])
    blue = colour_pixels(shot, (60, 150, 255), MAP)
    assert blue >= 20, f'no GPF track drawn (see {OUT / "fls.png"})'


def test_the_imaging_stack_shows_its_polar_frames(browser, tmp_path):
    from sonar_tracking.cli.view.scene import PANELS
    # 6 s of frames at --view's 4 frames a second (the stack's view_parameters); the diver is confirmed
    # after 3.0-3.6 s (seeds 1-6 of the scenario without ROS).
    page, names, saved, saved_names, scans, shot = run_in_browser(
        browser, 'imaging', tmp_path, '/map/tracks/confirmed/points', ('--set', 'seaking_sim.duration=6'))
    assert set(names) == set(saved_names) and {PANELS[k] for k in ('map', 'legend', 'polar')} <= set(names)
    import cv2
    polar = cv2.imdecode(np.frombuffer(bytes(page['/sector/polar']['EncodedImage:blob'][-1][1][0]), np.uint8),
                         cv2.IMREAD_GRAYSCALE)
    assert polar.shape[1] >= 512 and polar.std() > 5  # the 512 beams, with echoes in them
    assert colour_pixels(shot, (40, 220, 60), MAP) >= 20, f'no track drawn (see {OUT / "imaging.png"})'
