"""Pipeline messages -> Rerun entities: a map of the world frame, the sonar data in its polar form, a
legend and the time plots.

The map is a 2-D view with ``x`` to the right and ``y`` up (entity coordinates ``(x, -y)``, since a
Rerun 2-D view points its vertical axis down):

* ``map/fan``: the sonar sectors painted into a world-frame image (:class:`PolarCanvas`, the same
  painting as ``/sonar/fan``) at the platform pose from ``platform/odometry`` (else ``sonar_pose``);
  ``map/grid`` (faint lines at a round spacing) and ``map/scale`` (a bar labelled with that
  spacing) over it;
* ``map/fls_image``: the FLS front end's processed image, placed by its ``fls/image_info``;
* ``map/detections``, ``map/regions`` (ids on hover and selection, no label: a label would hide the
  track ids), ``map/truth/{points,tails}`` (white);
* ``map/tracks/confirmed/{points,tails,velocity,covariance}`` (green) and
  ``map/tracks/tentative/points`` (grey) for the IMM-IPDA tracks, ``map/gpf/...`` (blue) for the
  GPF tracks: points labelled ``T<id>``, the velocity arrow spanning ``arrow_seconds``, the
  covariance ellipse ``n_sigma`` standard deviations (:func:`sonar_tracking.msgs.covariance_ellipse`).
  Each point carries its record's details, shown when it is selected or hovered: existence and
  IMM mode probabilities of an IMM-IPDA track, the fusion rule in use (MF or WF) of a GPF track, speed.
  Tentative tracks are small points only: a clutter-rich scene has hundreds.

``sector/polar`` is the sonar data as it arrives, one column per beam (port on the left) and one row per
range bin (far range on top), the sectors of a scanning head side by side (:class:`PolarScan`);
``sector/ticks`` labels its bearings and ranges. ``legend`` names the colours of what is present.
Time plots under ``plots/``: ``threshold``, ``clutter_density``, ``confirmed/{imm_ipda,gpf}``
(confirmed tracks) and ``counts/*`` (tentative tracks, detections, regions per message).

Everything is logged on the ``time`` timeline: seconds since the first stamp the view logged
(header stamps; the Float64 threshold and density take the stamp of the last ``detections``, which
the detector publishes just before them), so a bag scrubs in sensor time; that first stamp is the
recording property ``run/first_stamp``. The layout (:func:`blueprint`) has a panel only for what
arrived: a stack without the ESC detector shows no threshold panel. The sonar images (fan and
polar) are logged at most once per ``fan_period`` of stamp time and, given a ``clock``, of that
clock's time too (:meth:`SceneLogger.flush_images` logs the latest one when the period is over), so
a fast pipeline does not flood the browser. A message that does not decode is counted in
:attr:`SceneLogger.errors` and dropped; per-message work and memory are bounded (tails keep
``tail`` points of tracks present in the latest message, the polar image at most
``PolarScan.MAX_ROWS`` x ``PolarScan.MAX_COLS`` pixels).
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from datetime import datetime, timezone
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

import sonar_tracking.msgs as ma
from sonar_tracking.cli.view import IMAGE_TOPICS, RECORD_TOPICS, TOPICS
from sonar_tracking.core.fan import PolarCanvas, fan_extent, to_mono8
from sonar_tracking.core.intensity import CODINGS, decode
from sonar_tracking.msgs.map_info import fls_image, map_info_to_grid

__all__ = ['TOPICS', 'IMAGE_TOPICS', 'RECORD_TOPICS', 'SceneLogger', 'PolarScan', 'blueprint', 'TIMELINE', 'PANELS',
           'grid_spacing']  # topics re-exported from the package

#: The timeline everything is logged on: seconds since the first stamp the view logged.
TIMELINE = 'time'

#: Panel names by role (the tests look for them in the layout).
PANELS = {
    'map': 'map: x right, y up [m]',
    'legend': 'legend',
    'polar': 'sonar data (polar): bearing across, port left; range up',
    'threshold': 'detection threshold',
    'clutter_density': 'clutter density [1/m^2]',
    'confirmed': 'confirmed tracks',
    'counts': 'per message: detections, tentative tracks, regions',
}

_DETECTION = (255, 160, 0)
_REGION = (255, 0, 200)
_CONFIRMED = {'tracks': (40, 220, 60), 'gpf/tracks': (60, 150, 255)}
_TENTATIVE = {'tracks': (160, 160, 160), 'gpf/tracks': (120, 120, 200)}
_TRUTH = (255, 255, 255)
_GRID = (90, 90, 90, 110)
_DARK = (16, 16, 16)
_ELLIPSE = np.linspace(0.0, 2.0 * math.pi, 25)
_PENDING_SECTORS = 2  # sectors waiting for the odometry of their stamp
_JPEG_QUALITY = 80

#: Legend entries by what arrived: (label, colour); images are grey, weak echoes dark.
_LEGEND = {
    'sector': [('sonar echo: dark weak, white strong (log scale)', (200, 200, 200))],
    'detections': [('detection', _DETECTION)],
    'truth': [('truth (simulated target) and its path', _TRUTH)],
    'tracks': [('IMM-IPDA track, confirmed: id, path, velocity, covariance', _CONFIRMED['tracks']),
               ('IMM-IPDA track, tentative', _TENTATIVE['tracks'])],
    'gpf': [('GPF track, confirmed: id, path, velocity, covariance', _CONFIRMED['gpf/tracks']),
            ('GPF track, tentative', _TENTATIVE['gpf/tracks'])],
    'regions': [('FLS region', _REGION)],
}
_LEGEND_ORDER = ('sector', 'detections', 'regions', 'truth', 'tracks', 'gpf')
_LEGEND_STEP = 1.0


def grid_spacing(extent: float, lines: int = 8) -> float:
    """A round spacing (1, 2 or 5 times a power of ten) giving about ``lines`` grid lines over ``extent``."""
    if not extent > 0:
        return 1.0
    raw = extent / lines
    power = 10.0 ** math.floor(math.log10(raw))
    return next(m * power for m in (1.0, 2.0, 5.0, 10.0) if m * power >= raw)


def blueprint(bounds: tuple[float, float, float, float] | None = None,
              present: frozenset[str] | set[str] = frozenset()) -> rrb.Blueprint:
    """The layout for what arrived (``present``: the keys of :data:`_LEGEND` plus ``threshold`` and
    ``clutter_density``): the map (showing ``bounds`` = ``(x_min, x_max, y_min, y_max)`` [m] if given)
    above the legend on the left; the polar sonar data and the time plots that have data on the right;
    the selection panel, which shows the details of a selected track, beside them."""
    visual = None if bounds is None else rrb.VisualBounds2D(x_range=[bounds[0], bounds[1]],
                                                            y_range=[-bounds[3], -bounds[2]])
    rows = max(1, sum(len(_LEGEND[k]) for k in _LEGEND_ORDER if k in present))
    # Labels are drawn centred under their points: the points sit on the middle line.
    legend_bounds = rrb.VisualBounds2D(x_range=[-10.0, 10.0], y_range=[-0.6, (rows - 0.1) * _LEGEND_STEP])
    # Dark behind the sonar pictures and the labels (the label boxes are light).
    left = rrb.Vertical(rrb.Spatial2DView(origin='map', name=PANELS['map'], visual_bounds=visual, background=_DARK),
                        rrb.Spatial2DView(origin='legend', name=PANELS['legend'], visual_bounds=legend_bounds,
                                          background=_DARK),
                        row_shares=[4, 1])
    right: list = []
    shares: list[float] = []
    if 'sector' in present:
        right.append(rrb.Spatial2DView(origin='sector', name=PANELS['polar'], background=_DARK))
        shares.append(2.0)
    for key, origin in (('threshold', 'plots/threshold'), ('clutter_density', 'plots/clutter_density')):
        if key in present:
            right.append(rrb.TimeSeriesView(origin=origin, name=PANELS[key]))
            shares.append(1.0)
    if present & {'tracks', 'gpf'}:
        right.append(rrb.TimeSeriesView(origin='plots/confirmed', name=PANELS['confirmed']))
        shares.append(1.0)
    if present & {'detections', 'tracks', 'gpf', 'regions'}:
        right.append(rrb.TimeSeriesView(origin='plots/counts', name=PANELS['counts']))
        shares.append(1.0)
    root = left if not right else rrb.Horizontal(left, rrb.Vertical(*right, row_shares=shares), column_shares=[3, 2])
    return rrb.Blueprint(root, rrb.BlueprintPanel(state='hidden'), rrb.SelectionPanel(state='expanded'),
                         rrb.TimePanel(state='collapsed', timeline=TIMELINE))


class PolarScan:
    """The sonar data in its own coordinates: a column per beam bearing, port (larger bearing) on the
    left, a row per range bin, far range on top. Sectors of a scanning head land side by side at their
    bearings (a new range scale or bearing step starts the picture anew); bins and beams beyond
    ``MAX_ROWS`` and ``MAX_COLS`` are thinned by an integer step."""

    MAX_ROWS = 512
    MAX_COLS = 1024

    def __init__(self) -> None:
        self.image: np.ndarray | None = None
        self.key: tuple | None = None
        self.top = 0.0  # bearing of column 0 [rad]
        self.step = 0.0  # bearing step between columns [rad]

    def paint(self, values: np.ndarray, geometry: Any) -> bool:
        """Put one sector ``(n_bins, n_beams)`` in; True if the picture started anew (new axes)."""
        rstep = -(-geometry.n_bins // self.MAX_ROWS)
        bstep = -(-geometry.n_beams // self.MAX_COLS)
        cells = np.asarray(values, np.float32)[::rstep, ::bstep][::-1, ::-1]
        step = geometry.angle_increment * bstep
        top = geometry.angle_min + (cells.shape[1] - 1) * step
        key = (geometry.range_min, geometry.range_max, geometry.n_bins, rstep, round(step, 12))
        if self.image is not None and key == self.key:
            c0 = int(round((self.top - top) / step))
            lo, hi = min(0, c0), max(self.image.shape[1], c0 + cells.shape[1])
            if hi - lo <= self.MAX_COLS:
                grows = lo < 0 or hi > self.image.shape[1]
                if grows:
                    grown = np.full((self.image.shape[0], hi - lo), np.nan, np.float32)
                    grown[:, -lo:-lo + self.image.shape[1]] = self.image
                    self.image, self.top = grown, self.top - lo * step
                    c0 -= lo
                self.image[:, c0:c0 + cells.shape[1]] = cells
                return grows
        self.image, self.key, self.top, self.step = cells.copy(), key, top, step
        return True

    @property
    def stretch(self) -> int:
        """Times each column is repeated in :meth:`picture`: a sector of few beams is shown at least
        1.5 times as wide as tall (its pixels are not square)."""
        if self.image is None:
            return 1
        rows, cols = self.image.shape
        return int(min(16, max(1, math.ceil(1.5 * rows / cols))))

    def picture(self, dynamic_range_db: float) -> np.ndarray:
        """The picture in grey levels (:func:`to_mono8`), columns repeated :attr:`stretch` times."""
        assert self.image is not None
        return np.ascontiguousarray(np.repeat(to_mono8(self.image, dynamic_range_db), self.stretch, axis=1))

    def ticks(self) -> tuple[np.ndarray, list[str]]:
        """Positions in the picture and labels of the bearings of its edges and middle (under it) and of
        the far and middle ranges (near its left edge), for reading the picture."""
        assert self.image is not None and self.key is not None
        rows, cols = self.image.shape
        k = self.stretch
        range_min, range_max = self.key[0], self.key[1]
        positions, labels = [], []
        for col in (0, (cols - 1) // 2, cols - 1):
            positions.append(((col + 0.5) * k, rows + 0.5))
            labels.append(f'{math.degrees(self.top - col * self.step):+.1f} deg')
        inset = 0.08 * cols * k  # labels are centred on their points: keep these inside the picture
        for row, rng in ((0, range_max), ((rows - 1) // 2, 0.5 * (range_min + range_max))):
            positions.append((inset, row + 0.5))
            labels.append(f'{rng:.4g} m')
        return np.array(positions, np.float32), labels


class SceneLogger:
    """Logs pipeline messages to a Rerun recording; :meth:`handle` takes one message of a topic.

    Parameters
    ----------
    rec : the recording to log to.
    fan_px : longer side of the world-frame fan image [px].
    fan_period : shortest interval between two logged sonar images [s of stamp time, and of ``clock``].
    record_period : shortest interval between two logged messages of one record topic (detections,
        tracks, truth, regions, the plotted scalars) [s of stamp time]; the newest message of a
        shorter interval is held and logged only if no later one came (:meth:`flush_images`,
        :meth:`finish`); 0 logs every message.
    coding : how sector values code the echo (:data:`sonar_tracking.core.intensity.CODINGS`).
    dynamic_range_db : grey scale of the fan, polar and FLS images above their median [dB].
    sonar_pose : ``(x, y, yaw)`` of the sonar in the world when no odometry arrives.
    tail : points kept per track and target tail.
    arrow_seconds : time span of the velocity arrows [s].
    n_sigma : size of the covariance ellipses [standard deviations].
    clock : seconds of a monotonic clock (live: ``time.monotonic``); None (a bag): stamp time only.
    """

    def __init__(self, rec: rr.RecordingStream, *, fan_px: int = 768, fan_period: float = 1.0,
                 coding: str = 'linear_amplitude', dynamic_range_db: float = 30.0,
                 sonar_pose: tuple[float, float, float] = (0.0, 0.0, 0.0), tail: int = 40,
                 arrow_seconds: float = 10.0, n_sigma: float = 2.0,
                 clock: Callable[[], float] | None = None, record_period: float = 0.0) -> None:
        if coding not in CODINGS:
            raise ValueError(f'coding {coding!r} is not one of {CODINGS}')
        if fan_px < 16 or tail < 1 or not (n_sigma > 0 and arrow_seconds >= 0 and fan_period >= 0
                                           and record_period >= 0):
            raise ValueError('need fan_px >= 16, tail >= 1, n_sigma > 0, arrow_seconds >= 0, fan_period >= 0, '
                             'record_period >= 0')
        self.record_period = float(record_period)
        self.held = 0                                   # record messages left out for a newer one
        self._held: dict[str, tuple[Any, float | None]] = {}
        self._record_ns: dict[str, int] = {}
        self.rec = rec
        self.fan_px, self.fan_period, self.coding = int(fan_px), float(fan_period), coding
        self.dynamic_range_db = float(dynamic_range_db)
        self.tail, self.arrow_seconds, self.n_sigma = int(tail), float(arrow_seconds), float(n_sigma)
        self.clock = clock
        self.counts: dict[str, int] = {}
        self.errors: dict[str, int] = {}
        self.last_error: dict[str, str] = {}
        self.present: set[str] = set()
        self.images_logged = 0
        self._pose = tuple(float(v) for v in sonar_pose)
        self._odom_ns = -1
        self._stamp_ns: int | None = None
        self._t0_ns: int | None = None
        self._det_ns: int | None = None
        self._sectors = ma.SectorPairer(max_pending=8)
        self._pending: deque = deque()
        self._canvas: PolarCanvas | None = None
        self._bounds: tuple[float, float, float, float] | None = None
        self._polar = PolarScan()
        self._painted_ns: int | None = None   # stamp of the latest sector painted but not yet logged
        # The latest sector not painted yet, with its pose: a later one over the same cells (the next
        # frame of an imaging sonar) replaces it unpainted.
        self._unpainted: tuple[int, np.ndarray, Any, tuple[float, ...]] | None = None
        self.frames_skipped = 0
        self._image_ns: int | None = None     # stamp and clock time of the latest logged images
        self._image_wall: float | None = None
        self._fls = ma.StampPairer(('image', 'info'), max_pending=4)
        self._tails: dict[str, dict[int, deque]] = {}
        self._handlers = {
            'sonar/sector': lambda m: self._sector(self._sectors.add_image(m)),
            'sonar/sector_info': lambda m: self._sector(self._sectors.add_info(m)),
            'platform/odometry': self._odometry,
            'sonar/truth': self._truth,
            'detections': self._detections,
            'detector/threshold': lambda m: self._scalar('threshold', m),
            'detector/clutter_density': lambda m: self._scalar('clutter_density', m),
            'tracks': lambda m: self._tracks('tracks', 'map/tracks', 'imm_ipda', m),
            'gpf/tracks': lambda m: self._tracks('gpf/tracks', 'map/gpf', 'gpf', m),
            'fls/image': lambda m: self._fls_image(self._fls.add('image', ma.header_ns(m), m)),
            'fls/image_info': lambda m: self._fls_image(self._fls.add('info', ma.stamp_to_ns(m.map_load_time), m)),
            'fls/regions': self._regions,
        }
        self._log_styles()

    def handle(self, topic: str, msg: Any) -> bool:
        """Log one message of a relative topic name (or hold it, see ``record_period``); False (and
        counted in ``errors``) if it was dropped."""
        handler = self._handlers.get(topic)
        if handler is None:
            return False
        if self.record_period > 0 and topic in RECORD_TOPICS:
            stamp_ns = self._record_stamp(msg)
            last = self._record_ns.get(topic)
            if stamp_ns is not None and last is not None and 0 <= stamp_ns - last < self.record_period * 1e9:
                if topic in self._held:
                    self.held += 1
                self._held[topic] = (msg, self.clock() if self.clock is not None else None)
                return True
            if self._held.pop(topic, None) is not None:
                self.held += 1
            if stamp_ns is not None:
                self._record_ns[topic] = stamp_ns
        return self._log(topic, handler, msg)

    def _log(self, topic: str, handler: Callable[[Any], None], msg: Any) -> bool:
        try:
            handler(msg)
        except (ma.AdapterError, ValueError, TypeError, AttributeError, IndexError) as exc:
            self.errors[topic] = self.errors.get(topic, 0) + 1
            self.last_error[topic] = f'{type(exc).__name__}: {exc}'
            return False
        self.counts[topic] = self.counts.get(topic, 0) + 1
        return True

    def _record_stamp(self, msg: Any) -> int | None:
        # Records carry a header; the plotted scalars (std_msgs) take the latest record's stamp.
        try:
            return ma.header_ns(msg)
        except (AttributeError, TypeError, ValueError):
            return self._stamp_ns

    def _flush_held(self, everything: bool) -> None:
        # A held message whose topic went quiet for a period (of ``clock``; at the end, any) is the newest.
        now = self.clock() if self.clock is not None else None
        for topic, (msg, since) in list(self._held.items()):
            if everything or (now is not None and since is not None and now - since >= self.record_period):
                del self._held[topic]
                self._log(topic, self._handlers[topic], msg)

    def finish(self) -> None:
        """Paint the sectors still waiting for odometry, log the held records and the latest sonar
        images (end of a run)."""
        self._flush_sectors(everything=True)
        self._paint_unpainted()
        self._flush_held(everything=True)
        if self._painted_ns is not None:
            self._log_images(self._painted_ns, force=True)

    def flush_images(self) -> bool:
        """Log records held for a ``record_period`` of ``clock`` with nothing newer, and the latest
        sonar images if some were held back and ``fan_period`` has passed since the last ones (call it
        periodically in a live view); True if it logged images."""
        self._flush_held(everything=False)
        logged = self.images_logged
        if self._unpainted is not None and self._period_over(self._unpainted[0]):
            self._paint_unpainted()                      # logs the images itself
        if self._painted_ns is not None and self._period_over(self._painted_ns):
            self._log_images(self._painted_ns, force=True)
        return self.images_logged > logged

    # -- time, layout and styles -----------------------------------------------------------------

    def _at(self, stamp_ns: int | None) -> None:
        if stamp_ns is None:  # nothing stamped yet: the start of the run
            self.rec.set_time(TIMELINE, duration=np.timedelta64(0, 'ns'))
            return
        if self._t0_ns is None:
            self._t0_ns = int(stamp_ns)
            first = datetime.fromtimestamp(stamp_ns // 10**9, tz=timezone.utc).strftime('%Y-%m-%dT%H:%M:%S')
            self.rec.send_property('run', rr.AnyValues(
                first_stamp=f'{first}.{stamp_ns % 10**9:09d}Z', first_stamp_ns=int(stamp_ns),
                timeline=f'{TIMELINE}: seconds since the first stamp'))
        self.rec.set_time(TIMELINE, duration=np.timedelta64(int(stamp_ns) - self._t0_ns, 'ns'))

    def _seen(self, *families: str) -> None:
        new = set(families) - self.present
        if not new:
            return
        self.present |= new
        self._log_legend()
        self.rec.send_blueprint(blueprint(self._bounds, frozenset(self.present)))

    def _log_legend(self) -> None:
        entries = [e for k in _LEGEND_ORDER if k in self.present for e in _LEGEND[k]]
        if not entries:
            return
        # First entry on top: rows go down the view.
        positions = np.array([(0.0, i * _LEGEND_STEP) for i in range(len(entries))], np.float32)
        self.rec.log('legend', rr.Points2D(positions, radii=rr.Radius.ui_points(6.0),
                                           colors=[c for _, c in entries], labels=[t for t, _ in entries],
                                           show_labels=True), static=True)

    def _log_styles(self) -> None:
        series = {
            'plots/threshold': ('threshold', (230, 60, 60)),
            'plots/clutter_density': ('clutter density', (70, 120, 255)),
            'plots/confirmed/imm_ipda': ('IMM-IPDA', _CONFIRMED['tracks']),
            'plots/confirmed/gpf': ('GPF', _CONFIRMED['gpf/tracks']),
            'plots/counts/tentative/imm_ipda': ('IMM-IPDA tentative', _TENTATIVE['tracks']),
            'plots/counts/tentative/gpf': ('GPF tentative', _TENTATIVE['gpf/tracks']),
            'plots/counts/detections': ('detections', _DETECTION),
            'plots/counts/regions': ('FLS regions', _REGION),
        }
        for path, (name, color) in series.items():
            self.rec.log(path, rr.SeriesLines(names=name, colors=[color]), static=True)

    # -- sonar images ----------------------------------------------------------------------------

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
            held = self._unpainted
            if held is not None:
                if held[2] == geometry:
                    self.frames_skipped += 1     # the same cells again: the older frame is never seen
                else:
                    self._paint(*held)           # another part of the fan (a scanning sonar): keep it
            self._unpainted = (stamp_ns, values, geometry, self._pose)
            self._stamp_ns = stamp_ns if self._stamp_ns is None else max(self._stamp_ns, stamp_ns)
            if self._period_over(stamp_ns):
                self._paint_unpainted()

    def _paint_unpainted(self) -> None:
        if self._unpainted is not None:
            held, self._unpainted = self._unpainted, None
            self._paint(*held)

    def _paint(self, stamp_ns: int, values: np.ndarray, geometry: Any, pose: tuple[float, ...]) -> None:
        self._seen('sector')
        x0, x1, y0, y1 = fan_extent(geometry)
        px, py, yaw = pose
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
            box = self._bounds = _canvas_box(cv)
            self.rec.log('map/fan', rr.Transform3D(translation=[box[0], -box[3], 0.0], scale=cv.resolution))
            self._log_grid(box)
            self.rec.send_blueprint(blueprint(box, frozenset(self.present)))  # the map starts on the sonar's picture
        cv.paint(values, geometry, pose)
        if self._polar.paint(values, geometry):
            self._at(stamp_ns)
            positions, labels = self._polar.ticks()
            self.rec.log('sector/ticks', rr.Points2D(positions, radii=rr.Radius.ui_points(0.5),
                                                     colors=[(230, 230, 230)], labels=labels, show_labels=True,
                                                     draw_order=5.0))
        self._stamp_ns = stamp_ns if self._stamp_ns is None else max(self._stamp_ns, stamp_ns)
        self._painted_ns = stamp_ns
        if self._period_over(stamp_ns):
            self._log_images(stamp_ns)

    def _period_over(self, stamp_ns: int) -> bool:
        if self._image_ns is not None and 0 <= stamp_ns - self._image_ns < self.fan_period * 1e9:
            return False
        return not (self.clock is not None and self._image_wall is not None
                    and self.clock() - self._image_wall < self.fan_period)

    def _log_images(self, stamp_ns: int, force: bool = False) -> None:
        if not force and not self._period_over(stamp_ns):
            return
        self._image_ns, self._painted_ns = stamp_ns, None
        self._image_wall = self.clock() if self.clock is not None else None
        self.images_logged += 1
        self._at(stamp_ns)
        # Canvas rows run down x and columns down y; the map wants columns along x and rows down -y.
        picture = np.ascontiguousarray(to_mono8(self._canvas.image, self.dynamic_range_db)[::-1, :].T)
        polar = self._polar.picture(self.dynamic_range_db)
        for path, image in (('map/fan', picture), ('sector/polar', polar)):
            self.rec.log(path, rr.Image(image, color_model='L', draw_order=-20.0).compress(jpeg_quality=_JPEG_QUALITY))

    def _log_grid(self, box: tuple[float, float, float, float]) -> None:
        x0, x1, y0, y1 = box
        step = grid_spacing(max(x1 - x0, y1 - y0))
        xs = np.arange(math.ceil(x0 / step), math.floor(x1 / step) + 1) * step
        ys = np.arange(math.ceil(y0 / step), math.floor(y1 / step) + 1) * step
        lines = [np.array([[x, -y0], [x, -y1]], np.float32) for x in xs]
        lines += [np.array([[x0, -y], [x1, -y]], np.float32) for y in ys]
        self.rec.log('map/grid', rr.LineStrips2D(lines, colors=[_GRID], radii=rr.Radius.ui_points(0.6),
                                                 draw_order=-5.0))
        # The scale bar: one grid spacing at the lower left corner, labelled.
        pad = 0.03 * max(x1 - x0, y1 - y0)
        bar = np.array([[x0 + pad, -(y0 + pad)], [x0 + pad + step, -(y0 + pad)]], np.float32)
        self.rec.log('map/scale', rr.LineStrips2D([bar], colors=[(255, 255, 255)], radii=rr.Radius.ui_points(2.0),
                                                  labels=[f'{step:g} m (grid {step:g} m)'], show_labels=True,
                                                  draw_order=30.0))

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
        self.rec.log('map/fls_image', rr.Image(picture, color_model='L', draw_order=-10.0).compress(
            jpeg_quality=_JPEG_QUALITY))

    # -- records ---------------------------------------------------------------------------------

    def _records(self, msg: Any, needed: tuple[str, ...]) -> np.ndarray:
        rec = np.array(ma.cloud_to_array(msg))
        names = rec.dtype.names or ()
        missing = [n for n in needed if n not in names]
        if missing:
            raise ma.AdapterError(f'records lack field(s) {missing}')
        stamp_ns = ma.header_ns(msg)
        self._at(stamp_ns)
        self._stamp_ns = stamp_ns if self._stamp_ns is None else max(self._stamp_ns, stamp_ns)
        finite = np.ones(len(rec), bool)
        for n in needed:
            if rec.dtype[n].kind == 'f':
                finite &= np.isfinite(rec[n])
        return rec[finite]

    def _detections(self, msg: Any) -> None:
        det = self._records(msg, ('x', 'y'))
        self._seen('detections')
        self._det_ns = self._stamp_ns
        self.rec.log('map/detections', rr.Points2D(_xy(det), radii=rr.Radius.ui_points(2.5), colors=[_DETECTION],
                                                   draw_order=10.0))
        self.rec.log('plots/counts/detections', rr.Scalars(float(len(det))))

    def _regions(self, msg: Any) -> None:
        reg = self._records(msg, ('region_id', 'x', 'y'))
        self._seen('regions')
        details = {'region_id': reg['region_id'].astype(np.int64)}
        if 'range' in reg.dtype.names and 'bearing' in reg.dtype.names:
            details.update(range_m=reg['range'], bearing_deg=np.degrees(reg['bearing']))
        # Unlabelled on the map (a label there would hide the track ids); the id shows on hover.
        self.rec.log('map/regions', rr.Points2D(_xy(reg), radii=rr.Radius.ui_points(4.0), colors=[_REGION],
                                                labels=[f'R{int(i)}' for i in reg['region_id']], show_labels=False,
                                                draw_order=11.0), *_details(len(reg), details))
        self.rec.log('plots/counts/regions', rr.Scalars(float(len(reg))))

    def _scalar(self, key: str, msg: Any) -> None:
        value = float(msg.data)
        if not math.isfinite(value):
            raise ValueError(f'plots/{key} is not finite: {value}')
        self._seen(key)
        self._at(self._stamp_ns if self._det_ns is None else self._det_ns)
        self.rec.log(f'plots/{key}', rr.Scalars(value))

    def _truth(self, msg: Any) -> None:
        truth = self._records(msg, ('target_id', 'x', 'y'))
        self._seen('truth')
        tails = self._update_tails('truth', truth['target_id'], truth)
        # Unlabelled (a label would hide the track's on top of it); the id is in the hover text.
        self.rec.log('map/truth/points', rr.Points2D(_xy(truth), radii=rr.Radius.ui_points(3.5), colors=[_TRUTH],
                                                     labels=[f'target {int(i)}' for i in truth['target_id']],
                                                     show_labels=False, draw_order=12.0),
                     *_details(len(truth), {'target_id': truth['target_id'].astype(np.int64)}))
        self.rec.log('map/truth/tails', rr.LineStrips2D([t.astype(np.float32) for t in tails], colors=[(*_TRUTH, 120)],
                                                        radii=rr.Radius.ui_points(1.5), draw_order=8.0))

    def _tracks(self, topic: str, base: str, plot: str, msg: Any) -> None:
        # ``plot``: the tracker's name under plots/confirmed and plots/counts/tentative.
        tracks = self._records(msg, ('track_id', 'x', 'y', 'vx', 'vy', 'cov_xx', 'cov_xy', 'cov_yy'))
        self._seen('tracks' if topic == 'tracks' else 'gpf')
        names = tracks.dtype.names
        confirmed = tracks['confirmed'] != 0 if 'confirmed' in names else np.ones(len(tracks), bool)
        self._update_tails(topic, tracks['track_id'], tracks)
        tails = self._tails[topic]
        for status, mask, color in (('confirmed', confirmed, _CONFIRMED[topic]), ('tentative', ~confirmed,
                                                                                  _TENTATIVE[topic])):
            sel = tracks[mask]
            xy = _xy(sel)
            path = f'{base}/{status}'
            full = status == 'confirmed'  # a clutter-rich scene has hundreds of tentative tracks: points only
            self.rec.log(f'{path}/points', rr.Points2D(
                xy, radii=rr.Radius.ui_points(5.0 if full else 2.0), colors=[color],
                labels=[f'T{int(i)}' for i in sel['track_id']] if full else None, show_labels=full, draw_order=20.0),
                *_details(len(sel), _track_details(sel, full)))
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


def _details(n: int, values: dict[str, Any]) -> list:
    """Per-point values to log beside the points (none for no points: Rerun refuses empty ones)."""
    return [rr.AnyValues(**values)] if n else []


def _track_details(sel: np.ndarray, full: bool) -> dict[str, Any]:
    """Per-track values shown on selection: id and existence always; for confirmed tracks speed,
    course, the IMM mode probabilities and the GPF fusion rule, where the record has them."""
    names = sel.dtype.names
    out: dict[str, Any] = {'track_id': sel['track_id'].astype(np.int64)}
    if 'existence' in names:
        out['existence'] = sel['existence']
    if not full:
        return out
    out['speed_m_s'] = np.hypot(sel['vx'], sel['vy'])
    out['course_deg'] = np.degrees(np.arctan2(sel['vy'], sel['vx']))
    for mode in ('mode_cv', 'mode_ccw', 'mode_cw'):
        if mode in names:
            out[mode] = sel[mode]
    if 'fusion' in names:
        out['fusion'] = ['WF (weighted sum)' if f else 'MF (multiplicative)' for f in sel['fusion']]
    return out


def _xy(rec: np.ndarray) -> np.ndarray:
    return np.column_stack([rec['x'], -rec['y']]).astype(np.float32)


def _canvas_box(cv: PolarCanvas) -> tuple[float, float, float, float]:
    return (cv.x_max - cv.height * cv.resolution, cv.x_max, cv.y_max - cv.width * cv.resolution, cv.y_max)


def _inside(a: tuple, b: tuple) -> bool:
    return a[0] >= b[0] and a[1] <= b[1] and a[2] >= b[2] and a[3] <= b[3]


def _union(a: tuple, b: tuple) -> tuple[float, float, float, float]:
    return (min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3]))
