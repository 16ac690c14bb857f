"""Pipeline messages -> Rerun entities: one map of the world frame and the time plots.

The map is a 2-D view with ``x`` to the right and ``y`` up (entity coordinates ``(x, -y)``, since a
Rerun 2-D view points its vertical axis down):

* ``map/fan``: the sonar sectors painted into a world-frame image (:class:`PolarCanvas`, the same
  painting as ``/sonar/fan``) at the platform pose from ``platform/odometry`` (else ``sonar_pose``);
* ``map/fls_image``: the FLS front end's processed image, placed by its ``fls/image_info``;
* ``map/detections``, ``map/regions`` (labelled ``R<id>``), ``map/truth/{points,tails}`` (white);
* ``map/tracks/confirmed/{points,tails,velocity,covariance}`` (green) and
  ``map/tracks/tentative/points`` (grey) for the IMM-IPDA tracks, ``map/gpf/...`` (blue) for the
  GPF tracks: points labelled ``T<id>``, the velocity arrow spanning ``arrow_seconds``, the
  covariance ellipse ``n_sigma`` standard deviations (:func:`sonar_tracking.msgs.covariance_ellipse`).
  Tentative tracks are small grey points only: a clutter-rich scene has hundreds.

Time plots under ``plots/``: ``threshold``, ``clutter_density``, ``confirmed/{imm_ipda,gpf}``
(confirmed tracks) and ``counts/*`` (tentative tracks, detections, regions per message).
Everything is logged on the ``stamp`` timeline (header stamps; the Float64 threshold and density
take the stamp of the last ``detections``, which the detector publishes just before them), so a
bag scrubs in sensor time. A message that does not decode is counted in :attr:`SceneLogger.errors`
and dropped; per-message work and memory are bounded (tails keep ``tail`` points of tracks present
in the latest message).
"""
from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

import sonar_tracking.msgs as ma
from sonar_tracking.cli.view import IMAGE_TOPICS, TOPICS
from sonar_tracking.core.fan import PolarCanvas, fan_extent, to_mono8
from sonar_tracking.core.intensity import CODINGS, decode
from sonar_tracking.msgs.map_info import fls_image, map_info_to_grid

__all__ = ['TOPICS', 'IMAGE_TOPICS', 'SceneLogger', 'blueprint']  # topics re-exported from the package

_CONFIRMED = {'tracks': (40, 220, 60), 'gpf/tracks': (60, 150, 255)}
_TENTATIVE = (160, 160, 160)
_TRUTH = (255, 255, 255)
_ELLIPSE = np.linspace(0.0, 2.0 * math.pi, 25)
_PENDING_SECTORS = 2  # sectors waiting for the odometry of their stamp


def blueprint(bounds: tuple[float, float, float, float] | None = None) -> rrb.Blueprint:
    """The layout: the map on the left (showing ``bounds`` = ``(x_min, x_max, y_min, y_max)`` [m] if
    given), threshold, clutter density and counts over time on the right."""
    visual = None if bounds is None else rrb.VisualBounds2D(x_range=[bounds[0], bounds[1]],
                                                            y_range=[-bounds[3], -bounds[2]])
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(origin='map', name='map: x right, y up [m]', visual_bounds=visual),
            rrb.Vertical(
                rrb.TimeSeriesView(origin='plots/threshold', name='detection threshold'),
                rrb.TimeSeriesView(origin='plots/clutter_density', name='clutter density [1/m^2]'),
                rrb.TimeSeriesView(origin='plots/confirmed', name='confirmed tracks'),
                rrb.TimeSeriesView(origin='plots/counts', name='tentative tracks, detections, regions'),
            ),
            column_shares=[3, 2]),
        collapse_panels=True)


class SceneLogger:
    """Logs pipeline messages to a Rerun recording; :meth:`handle` takes one message of a topic.

    Parameters
    ----------
    rec : the recording to log to.
    fan_px : longer side of the world-frame fan image [px].
    fan_period : shortest interval between two logged fan images [s of stamp time].
    coding : how sector values code the echo (:data:`sonar_tracking.core.intensity.CODINGS`).
    dynamic_range_db : grey scale of the fan and FLS images above their median [dB].
    sonar_pose : ``(x, y, yaw)`` of the sonar in the world when no odometry arrives.
    tail : points kept per track and target tail.
    arrow_seconds : time span of the velocity arrows [s].
    n_sigma : size of the covariance ellipses [standard deviations].
    """

    def __init__(self, rec: rr.RecordingStream, *, fan_px: int = 768, fan_period: float = 0.5,
                 coding: str = 'linear_amplitude', dynamic_range_db: float = 30.0,
                 sonar_pose: tuple[float, float, float] = (0.0, 0.0, 0.0), tail: int = 40,
                 arrow_seconds: float = 10.0, n_sigma: float = 2.0) -> None:
        if coding not in CODINGS:
            raise ValueError(f'coding {coding!r} is not one of {CODINGS}')
        if fan_px < 16 or tail < 1 or not (n_sigma > 0 and arrow_seconds >= 0 and fan_period >= 0):
            raise ValueError('need fan_px >= 16, tail >= 1, n_sigma > 0, arrow_seconds >= 0, fan_period >= 0')
        self.rec = rec
        self.fan_px, self.fan_period, self.coding = int(fan_px), float(fan_period), coding
        self.dynamic_range_db = float(dynamic_range_db)
        self.tail, self.arrow_seconds, self.n_sigma = int(tail), float(arrow_seconds), float(n_sigma)
        self.counts: dict[str, int] = {}
        self.errors: dict[str, int] = {}
        self.last_error: dict[str, str] = {}
        self._pose = tuple(float(v) for v in sonar_pose)
        self._odom_ns = -1
        self._stamp_ns = 0
        self._det_ns: int | None = None
        self._sectors = ma.SectorPairer(max_pending=8)
        self._pending: deque = deque()
        self._canvas: PolarCanvas | None = None
        self._fan_logged_ns: int | None = None
        self._fls = ma.StampPairer(('image', 'info'), max_pending=4)
        self._tails: dict[str, dict[int, deque]] = {}
        self._handlers = {
            'sonar/sector': lambda m: self._sector(self._sectors.add_image(m)),
            'sonar/sector_info': lambda m: self._sector(self._sectors.add_info(m)),
            'platform/odometry': self._odometry,
            'sonar/truth': self._truth,
            'detections': self._detections,
            'detector/threshold': lambda m: self._scalar('plots/threshold', m),
            'detector/clutter_density': lambda m: self._scalar('plots/clutter_density', m),
            'tracks': lambda m: self._tracks('tracks', 'map/tracks', 'imm_ipda', m),
            'gpf/tracks': lambda m: self._tracks('gpf/tracks', 'map/gpf', 'gpf', m),
            'fls/image': lambda m: self._fls_image(self._fls.add('image', ma.header_ns(m), m)),
            'fls/image_info': lambda m: self._fls_image(self._fls.add('info', ma.stamp_to_ns(m.map_load_time), m)),
            'fls/regions': self._regions,
        }
        self._log_styles()

    def handle(self, topic: str, msg: Any) -> bool:
        """Log one message of a relative topic name; False (and counted in ``errors``) if it was dropped."""
        handler = self._handlers.get(topic)
        if handler is None:
            return False
        try:
            handler(msg)
        except (ma.AdapterError, ValueError, TypeError, AttributeError, IndexError) as exc:
            self.errors[topic] = self.errors.get(topic, 0) + 1
            self.last_error[topic] = f'{type(exc).__name__}: {exc}'
            return False
        self.counts[topic] = self.counts.get(topic, 0) + 1
        return True

    def finish(self) -> None:
        """Paint the sectors still waiting for odometry and log the last fan image (end of a bag)."""
        self._flush_sectors(everything=True)
        if self._canvas is not None and self._fan_logged_ns != self._stamp_ns:
            self._log_fan(self._stamp_ns, force=True)

    # -- time and styles -------------------------------------------------------------------------

    def _at(self, stamp_ns: int) -> None:
        self.rec.set_time('stamp', timestamp=np.datetime64(int(stamp_ns), 'ns'))

    def _log_styles(self) -> None:
        series = {
            'plots/threshold': ('threshold', (230, 60, 60)),
            'plots/clutter_density': ('clutter density', (70, 120, 255)),
            'plots/confirmed/imm_ipda': ('IMM-IPDA', _CONFIRMED['tracks']),
            'plots/confirmed/gpf': ('GPF', _CONFIRMED['gpf/tracks']),
            'plots/counts/tentative/imm_ipda': ('IMM-IPDA tentative', _TENTATIVE),
            'plots/counts/tentative/gpf': ('GPF tentative', (120, 120, 200)),
            'plots/counts/detections': ('detections', (255, 160, 0)),
            'plots/counts/regions': ('FLS regions', (255, 0, 200)),
        }
        for path, (name, color) in series.items():
            self.rec.log(path, rr.SeriesLines(names=name, colors=[color]), static=True)

    # -- sonar image -----------------------------------------------------------------------------

    def _odometry(self, msg: Any) -> None:
        pose = ma.odometry_to_pose(msg)
        self._pose, self._odom_ns = pose, ma.header_ns(msg)
        self._flush_sectors()

    def _sector(self, pair: ma.SectorPair | None) -> None:
        self._sectors.pop_dropped()
        if pair is None:
            return
        amplitudes, geometry = ma.sector_from_messages(pair.image, pair.info)
        self._pending.append((pair.stamp_ns, decode(np.asarray(amplitudes), self.coding), geometry))
        self._flush_sectors()

    def _flush_sectors(self, everything: bool = False) -> None:
        # The simulator publishes a sector before the odometry of its stamp: paint once that came.
        while self._pending and (everything or self._pending[0][0] <= self._odom_ns
                                 or len(self._pending) > _PENDING_SECTORS):
            stamp_ns, values, geometry = self._pending.popleft()
            self._paint(stamp_ns, values, geometry)

    def _paint(self, stamp_ns: int, values: np.ndarray, geometry: Any) -> None:
        x0, x1, y0, y1 = fan_extent(geometry)
        px, py, yaw = self._pose
        c, s = math.cos(yaw), math.sin(yaw)
        corners = np.array([[x0, y0], [x0, y1], [x1, y0], [x1, y1]])
        wx, wy = px + corners @ np.array([c, -s]), py + corners @ np.array([s, c])
        box = (wx.min(), wx.max(), wy.min(), wy.max())
        cv = self._canvas
        if cv is None or not _inside(box, _canvas_box(cv)):
            union = box if cv is None else _union(box, _canvas_box(cv))
            # A platform that moved far starts a new picture rather than growing it without bound.
            if max(union[1] - union[0], union[3] - union[2]) > 4.0 * (geometry.range_max + geometry.range_resolution):
                union = box
            margin = 0.05 * max(union[1] - union[0], union[3] - union[2])
            cv = self._canvas = PolarCanvas.with_size(
                (union[0] - margin, union[1] + margin, union[2] - margin, union[3] + margin), self.fan_px)
            self._at(stamp_ns)
            box = _canvas_box(cv)
            self.rec.log('map/fan', rr.Transform3D(translation=[box[0], -box[3], 0.0], scale=cv.resolution))
            self.rec.send_blueprint(blueprint(box))  # the map starts on the sonar's picture
        cv.paint(values, geometry, self._pose)
        self._stamp_ns = max(self._stamp_ns, stamp_ns)
        self._log_fan(stamp_ns)

    def _log_fan(self, stamp_ns: int, force: bool = False) -> None:
        last = self._fan_logged_ns
        if not force and last is not None and 0 <= stamp_ns - last < self.fan_period * 1e9:
            return
        self._fan_logged_ns = stamp_ns
        self._at(stamp_ns)
        # Canvas rows run down x and columns down y; the map wants columns along x and rows down -y.
        picture = np.ascontiguousarray(to_mono8(self._canvas.image, self.dynamic_range_db)[::-1, :].T)
        self.rec.log('map/fan', rr.Image(picture, color_model='L', draw_order=-20.0).compress(jpeg_quality=90))

    def _fls_image(self, frame: dict | None) -> None:
        self._fls.pop_dropped()
        if frame is None:
            return
        image, info = frame['image'], frame['info']
        grid = map_info_to_grid(info)
        values = fls_image(image, grid.shape)
        stamp_ns = ma.header_ns(image)
        self._at(stamp_ns)
        c, s, h = math.cos(grid.origin_yaw), math.sin(grid.origin_yaw), grid.height * grid.resolution
        # Rows flipped so that pixels map to the map by a rotation and a scale (no mirror).
        self.rec.log('map/fls_image', rr.Transform3D(
            translation=[grid.origin_x - s * h, -grid.origin_y - c * h, 0.0],
            rotation=rr.RotationAxisAngle(axis=[0.0, 0.0, 1.0], radians=-grid.origin_yaw), scale=grid.resolution))
        picture = np.ascontiguousarray(to_mono8(values, self.dynamic_range_db)[::-1])
        self.rec.log('map/fls_image', rr.Image(picture, color_model='L', draw_order=-10.0).compress(jpeg_quality=90))

    # -- records ---------------------------------------------------------------------------------

    def _records(self, msg: Any, needed: tuple[str, ...]) -> np.ndarray:
        rec = np.array(ma.cloud_to_array(msg))
        names = rec.dtype.names or ()
        missing = [n for n in needed if n not in names]
        if missing:
            raise ma.AdapterError(f'records lack field(s) {missing}')
        stamp_ns = ma.header_ns(msg)
        self._at(stamp_ns)
        self._stamp_ns = max(self._stamp_ns, stamp_ns)
        finite = np.ones(len(rec), bool)
        for n in needed:
            if rec.dtype[n].kind == 'f':
                finite &= np.isfinite(rec[n])
        return rec[finite]

    def _detections(self, msg: Any) -> None:
        det = self._records(msg, ('x', 'y'))
        self._det_ns = self._stamp_ns
        self.rec.log('map/detections', rr.Points2D(_xy(det), radii=rr.Radius.ui_points(2.5), colors=[(255, 160, 0)],
                                                   draw_order=10.0))
        self.rec.log('plots/counts/detections', rr.Scalars(float(len(det))))

    def _regions(self, msg: Any) -> None:
        reg = self._records(msg, ('region_id', 'x', 'y'))
        self.rec.log('map/regions', rr.Points2D(_xy(reg), radii=rr.Radius.ui_points(4.0), colors=[(255, 0, 200)],
                                                labels=[f'R{int(i)}' for i in reg['region_id']], draw_order=11.0))
        self.rec.log('plots/counts/regions', rr.Scalars(float(len(reg))))

    def _scalar(self, path: str, msg: Any) -> None:
        value = float(msg.data)
        if not math.isfinite(value):
            raise ValueError(f'{path} is not finite: {value}')
        self._at(self._stamp_ns if self._det_ns is None else self._det_ns)
        self.rec.log(path, rr.Scalars(value))

    def _truth(self, msg: Any) -> None:
        truth = self._records(msg, ('target_id', 'x', 'y'))
        tails = self._update_tails('truth', truth['target_id'], truth)
        # Unlabelled (a label would hide the track's on top of it); the id is in the hover text.
        self.rec.log('map/truth/points', rr.Points2D(_xy(truth), radii=rr.Radius.ui_points(3.5), colors=[_TRUTH],
                                                     labels=[f'target {int(i)}' for i in truth['target_id']],
                                                     show_labels=False, draw_order=12.0))
        self.rec.log('map/truth/tails', rr.LineStrips2D([t.astype(np.float32) for t in tails], colors=[(*_TRUTH, 120)],
                                                        radii=rr.Radius.ui_points(1.5), draw_order=8.0))

    def _tracks(self, topic: str, base: str, plot: str, msg: Any) -> None:
        # ``plot``: the tracker's name under plots/confirmed and plots/counts/tentative.
        tracks = self._records(msg, ('track_id', 'x', 'y', 'vx', 'vy', 'cov_xx', 'cov_xy', 'cov_yy'))
        confirmed = tracks['confirmed'] != 0 if 'confirmed' in tracks.dtype.names else np.ones(len(tracks), bool)
        self._update_tails(topic, tracks['track_id'], tracks)
        tails = self._tails[topic]
        for status, mask, color in (('confirmed', confirmed, _CONFIRMED[topic]), ('tentative', ~confirmed, _TENTATIVE)):
            sel = tracks[mask]
            xy = _xy(sel)
            path = f'{base}/{status}'
            full = status == 'confirmed'  # a clutter-rich scene has hundreds of tentative tracks: points only
            self.rec.log(f'{path}/points', rr.Points2D(
                xy, radii=rr.Radius.ui_points(5.0 if full else 2.0), colors=[color],
                labels=[f'T{int(i)}' for i in sel['track_id']] if full else None, show_labels=full, draw_order=20.0))
            if full:
                vel = (np.column_stack([sel['vx'], -sel['vy']]) * self.arrow_seconds).astype(np.float32)
                self.rec.log(f'{path}/velocity', rr.Arrows2D(origins=xy, vectors=vel, colors=[color],
                                                             radii=rr.Radius.ui_points(1.5), draw_order=16.0))
                self.rec.log(f'{path}/tails', rr.LineStrips2D(
                    [np.array(tails[int(i)], np.float32) for i in sel['track_id']], colors=[color],
                    radii=rr.Radius.ui_points(1.5), draw_order=15.0))
                self.rec.log(f'{path}/covariance', rr.LineStrips2D(
                    [self._ellipse(r) for r in sel], colors=[(*color, 180)], radii=rr.Radius.ui_points(1.0),
                    draw_order=14.0))
            counts = f'plots/confirmed/{plot}' if full else f'plots/counts/tentative/{plot}'
            self.rec.log(counts, rr.Scalars(float(mask.sum())))

    def _ellipse(self, r: np.void) -> np.ndarray:
        major, minor, yaw = ma.covariance_ellipse(float(r['cov_xx']), float(r['cov_xy']), float(r['cov_yy']),
                                                  self.n_sigma)
        a, b = 0.5 * major, 0.5 * minor
        c, s = math.cos(yaw), math.sin(yaw)
        ex, ey = a * np.cos(_ELLIPSE), b * np.sin(_ELLIPSE)
        return np.column_stack([r['x'] + c * ex - s * ey, -(r['y'] + s * ex + c * ey)]).astype(np.float32)

    def _update_tails(self, key: str, ids: np.ndarray, rec: np.ndarray) -> list[np.ndarray]:
        old = self._tails.get(key, {})
        new = {}
        for i, x, y in zip(ids.tolist(), rec['x'].tolist(), rec['y'].tolist()):
            tail = old.get(i) or deque(maxlen=self.tail)
            tail.append((x, -y))
            new[i] = tail
        self._tails[key] = new  # tracks that ended leave with their tails
        return [np.array(t) for t in new.values()]


def _xy(rec: np.ndarray) -> np.ndarray:
    return np.column_stack([rec['x'], -rec['y']]).astype(np.float32)


def _canvas_box(cv: PolarCanvas) -> tuple[float, float, float, float]:
    return (cv.x_max - cv.height * cv.resolution, cv.x_max, cv.y_max - cv.width * cv.resolution, cv.y_max)


def _inside(a: tuple, b: tuple) -> bool:
    return a[0] >= b[0] and a[1] <= b[1] and a[2] >= b[2] and a[3] <= b[3]


def _union(a: tuple, b: tuple) -> tuple[float, float, float, float]:
    return (min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3]))
