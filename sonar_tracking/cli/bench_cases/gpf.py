"""GPF tracker speed (issue 9): 300 particles and the paper's five features per target.

Frames: a tank image of 428 x 300 pixels of 0.1 m (the size ``fls_features`` makes for FLS Table 5:
30 m range, +/-45 deg), speckle-like background near 1 and five towed-target echoes 2-3 m apart,
moving at 0.25 m/s, 5 s apart (one sweep), each with its region; built once, before timing.

* ``gpf.track_step``: one target's GPF step, the per-target work of a frame: prediction
  (eqs. 9-12: 300 samples moved by the motion model) and update (300 samples, the window features
  20, 17, 3, 6, 24 of every particle, the five likelihoods of eq. 13, the adaptive fusion with the
  cue spreads of eqs. 16-18 and the fuzzy weights, the posterior moments, the match at the
  estimate), on a frame prepared once for all targets. Target: < 5 ms.
* ``gpf.frame_5_targets``: ``GpfTracker.step`` on a frame with five confirmed tracks: image check and
  preparation, five predictions and updates, templates, re-finding, births. Target: < 25 ms.
* ``gpf.frame_1_target``: the same with one target.
* ``gpf.frame_15_targets``: ``GpfTracker.step`` with 15 confirmed tracks of 300 particles on a
  400 x 400 frame of 0.1 m (7-pixel windows); targets on a 3 x 5 lattice 3 m by 2.5 m apart.
  Targets: < 20 ms (issue 24), < 30 ms (issue 19).
* ``gpf.frame_15_targets_fine``: the same on a 400 x 400 frame of 0.05 m (15-pixel windows, the
  pixel size of a high-frequency imaging sonar), and ``gpf.frame_15_targets_2cm`` on a 1000 x 1000
  frame of 0.02 m (35-pixel windows on the image's own pixels). The tracker measures the windows on
  the image block-averaged to 0.1 m (``cues.pixel``), so both cost about what the 0.1 m frame does.
* ``gpf.windows_300`` against ``gpf.patch_features_300``: the five features of 300 particle windows
  by the window path and by the general region path of ``core.fls`` (same values).
* ``gpf.sir_track_step`` and ``gpf.ekf_frame_5_targets``: the baselines of Figure 13.
"""
from __future__ import annotations

import copy
import time

import numpy as np

from sonar_tracking.cli.bench import Case, register

N_FRAMES = 40
DT = 5.0
SPEED = 0.25


#: The scenes: (resolution [m], width, height [pixels], x of the targets' centre at frame 0 [m], frames).
TANK = (0.1, 300, 428, 25.0, N_FRAMES)
SQUARE = (0.1, 400, 400, 30.0, 16)
FINE = (0.05, 400, 400, 16.0, 8)
FINEST = (0.02, 1000, 1000, 16.0, 8)


def _grid(scene=TANK):
    from sonar_tracking.core.fls import ImageGrid
    res, width, height = scene[:3]
    return ImageGrid(resolution=res, width=width, height=height, origin_x=0.0, origin_y=-0.5 * height * res)


def _targets(k: int, n: int, scene=TANK) -> np.ndarray:
    """Positions ``(n, 2)`` of n targets at frame k, moving toward the sonar: up to five side by side
    2.5 m apart, more on a lattice of five columns 2.5 m apart and rows 3 m apart."""
    y = (np.arange(n) % 5 - (min(n, 5) - 1) / 2.0) * 2.5
    rows = np.arange(n) // 5
    x = scene[3] - SPEED * DT * (k % scene[4]) + (rows - rows.mean()) * 3.0
    return np.column_stack([x, y])


def _frames(n_targets: int, scene=TANK):
    """``(stamp, image, regions)`` of the scene's frames."""
    from sonar_tracking.core.records import REGION_DTYPE
    grid = _grid(scene)
    rng = np.random.default_rng(9)
    rows, cols = np.indices(grid.shape)
    out = []
    blob = 0.1 / grid.resolution   # echo size in pixels scales with the pixel size
    for k in range(scene[4]):
        img = rng.gamma(16.0, 1.0 / 16.0, grid.shape)
        xy = _targets(k, n_targets, scene)
        for x, y in xy:
            r, c = grid.point_to_pixel(x, y)
            img += 10.0 * np.exp(-0.5 * (((cols - c) / (1.5 * blob)) ** 2 + ((rows - r) / (4.0 * blob)) ** 2))
        reg = np.zeros(n_targets, REGION_DTYPE)
        reg['region_id'] = np.arange(1, n_targets + 1)
        reg['x'], reg['y'] = xy[:, 0], xy[:, 1]
        out.append((DT * k, img.astype(np.float32), reg))
    return grid, out


def _warm_tracker(n_targets: int, method: str = 'gpf', scene=TANK):
    from sonar_tracking.core.gpf import GpfTracker
    grid, frames = _frames(n_targets, scene)
    tracker = GpfTracker(rng=np.random.default_rng(3), method=method)
    for stamp, img, reg in frames[:3]:
        tracker.step(stamp, img, grid, reg, (0.0, 0.0, 0.0))
    if sum(t.confirmed for t in tracker.tracks) != n_targets:
        raise RuntimeError(f'bench tracker holds {len(tracker.tracks)} tracks, not {n_targets} confirmed ones')
    return tracker, grid, frames


def _track_step(method: str):
    def make():
        tracker, grid, frames = _warm_tracker(1, method)
        frame = tracker.prepare(frames[3][1], grid)
        base = tracker.tracks[0]

        def one() -> float:
            tr = copy.deepcopy(base)
            t0 = time.perf_counter()
            tracker.predict_track(tr, DT)
            tracker.update_track(tr, frame)
            return time.perf_counter() - t0
        return one
    return make


def _frame_step(n_targets: int, scene=TANK):
    def make():
        state = {}

        def restart():
            state['tracker'], state['grid'], state['frames'] = _warm_tracker(n_targets, scene=scene)
            state['k'] = 3

        restart()

        def one() -> float:
            if state['k'] >= len(state['frames']):
                restart()                       # untimed: a fresh tracker warmed up again
            stamp, img, reg = state['frames'][state['k']]
            state['k'] += 1
            tracker = state['tracker']
            t0 = time.perf_counter()
            tracker.step(stamp, img, state['grid'], reg, (0.0, 0.0, 0.0))
            return time.perf_counter() - t0
        return one
    return make


def _ekf_frame(n_targets: int):
    def make():
        from sonar_tracking.core.gpf import EkfTracker
        grid, frames = _frames(n_targets)
        state = {}

        def restart():
            state['tracker'] = EkfTracker()
            for stamp, _, reg in frames[:3]:
                state['tracker'].step(stamp, reg, (0.0, 0.0, 0.0))
            state['k'] = 3

        restart()

        def one() -> float:
            if state['k'] >= N_FRAMES:
                restart()
            stamp, _, reg = frames[state['k']]
            state['k'] += 1
            t0 = time.perf_counter()
            state['tracker'].step(stamp, reg, (0.0, 0.0, 0.0))
            return time.perf_counter() - t0
        return one
    return make


def _windows(general: bool):
    def make():
        from sonar_tracking.core.fls import PAPER_FEATURES, patch_features
        from sonar_tracking.core.fls.windows import WindowImage
        grid, frames = _frames(1)
        wi = WindowImage(frames[0][1])
        rng = np.random.default_rng(4)
        r, c = grid.point_to_pixel(*_targets(0, 1)[0])
        rows = np.rint(r + rng.normal(0, 6, 300)).astype(np.int64)
        cols = np.rint(c + rng.normal(0, 6, 300)).astype(np.int64)
        if not general:
            return lambda: wi.features(rows, cols, 7, PAPER_FEATURES)
        patches = wi.patches(rows, cols, 7)
        masks = np.zeros(patches.shape, bool)
        masks[:, 1:-1, 1:-1] = True
        return lambda: patch_features(patches, masks, features=PAPER_FEATURES)
    return make


register(Case(name='gpf.track_step', group='gpf', make=_track_step('gpf'), self_timed=True, repeats=200,
              limit_s=5e-3, description='GPF step of one target: 300 particles, features 20, 17, 3, 6, 24, '
                                        'adaptive fusion (predict + update, core)'))
register(Case(name='gpf.frame_5_targets', group='gpf', make=_frame_step(5), self_timed=True, repeats=74,
              limit_s=25e-3, description='GpfTracker.step, 428 x 300 frame with 5 confirmed tracks (core)'))
register(Case(name='gpf.frame_1_target', group='gpf', make=_frame_step(1), self_timed=True, repeats=74,
              description='GpfTracker.step, 428 x 300 frame with 1 confirmed track (core)'))
register(Case(name='gpf.frame_15_targets', group='gpf', make=_frame_step(15, SQUARE), self_timed=True, repeats=65,
              limit_s=20e-3, description='GpfTracker.step, 400 x 400 frame of 0.1 m with 15 confirmed tracks, '
                                         '300 particles each (core)'))
register(Case(name='gpf.frame_15_targets_fine', group='gpf', make=_frame_step(15, FINE), self_timed=True, repeats=50,
              description='the same on a 400 x 400 frame of 0.05 m: 15-pixel windows (core)'))
register(Case(name='gpf.frame_15_targets_2cm', group='gpf', make=_frame_step(15, FINEST), self_timed=True,
              repeats=30, description='the same on a 1000 x 1000 frame of 0.02 m (core)'))
register(Case(name='gpf.windows_300', group='gpf', make=_windows(False), repeats=50,
              compare_to='gpf.patch_features_300',
              description='features 20, 17, 3, 6, 24 of 300 windows of 7 x 7 pixels (core.fls.windows)'))
register(Case(name='gpf.patch_features_300', group='gpf', make=_windows(True), repeats=20,
              description='the same values by core.fls.patch_features (general region path)'))
register(Case(name='gpf.sir_track_step', group='gpf', make=_track_step('sir'), self_timed=True, repeats=200,
              description='SIR particle filter baseline: one target, same cues (core)'))
register(Case(name='gpf.ekf_frame_5_targets', group='gpf', make=_ekf_frame(5), self_timed=True, repeats=74,
              description='EKF baseline on the regions of the same frames, 5 tracks (core)'))

__all__ = ['N_FRAMES']
