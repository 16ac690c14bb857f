"""The gpf_tracker node over real DDS: frames from fls_features on the simulator, synthetic frames for
what the node must survive (an empty image, a frame without regions, bad input), parameters."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

import sonar_tracking.msgs as ma
from sonar_tracking.core.fls import ImageGrid
from sonar_tracking.msgs.map_info import grid_to_map_info

pytestmark = pytest.mark.ros

KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
CONFIG = Path(__file__).resolve().parents[2] / 'config' / 'gpf_tracker.yaml'
GRID = ImageGrid(resolution=0.1, width=200, height=160, origin_x=0.0, origin_y=-8.0)


def synthetic_frame(rng, target_xy, shape=GRID.shape) -> np.ndarray:
    """A processed image: background near 1, a bright 0.3 x 0.9 m echo at ``target_xy`` (if any)."""
    img = rng.gamma(16.0, 1.0 / 16.0, shape).astype(np.float32)
    if target_xy is not None:
        r, c = GRID.point_to_pixel(*target_xy)
        rows, cols = np.indices(shape)
        img += (12.0 * np.exp(-0.5 * (((cols - c) / 1.5) ** 2 + ((rows - r) / 4.0) ** 2))).astype(np.float32)
    return img


def regions_at(*points) -> np.ndarray:
    rec = np.zeros(len(points), ma.REGION_DTYPE)
    for i, (x, y) in enumerate(points):
        rec[i]['region_id'], rec[i]['x'], rec[i]['y'] = i + 1, x, y
        rec[i]['range'], rec[i]['bearing'] = math.hypot(x, y), math.atan2(y, x)
    return rec


class Harness:
    """Publishes FLS frames to the tracker and collects its outputs."""

    def __init__(self, ros, launch, proc):
        from diagnostic_msgs.msg import DiagnosticArray
        from nav_msgs.msg import MapMetaData
        from sensor_msgs.msg import Image, PointCloud2
        from visualization_msgs.msg import MarkerArray
        self.ros, self.launch, self.proc = ros, launch, proc
        node = ros.node
        self.pub_info = node.create_publisher(MapMetaData, '/fls/image_info', KEEP_ALL)
        self.pub_image = node.create_publisher(Image, '/fls/image', KEEP_ALL)
        self.pub_regions = node.create_publisher(PointCloud2, '/fls/regions', KEEP_ALL)
        self.tracks, self.markers, self.diagnostics = [], [], []
        self.subs = [node.create_subscription(PointCloud2, '/gpf/tracks', self.tracks.append, KEEP_ALL),
                     node.create_subscription(MarkerArray, '/gpf/tracks/markers', self.markers.append, KEEP_ALL),
                     node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, KEEP_ALL)]
        # Our readers must be matched with the node's writers too, or its first outputs are lost.
        ros.wait(lambda: all(p.get_subscription_count() > 0 for p in (self.pub_info, self.pub_image, self.pub_regions))
                 and all(s.get_publisher_count() > 0 for s in self.subs), 30.0, 'the tracker to come up')

    def _on_diag(self, msg):
        self.diagnostics.extend(s for s in msg.status if s.name.startswith('gpf_tracker'))

    def send(self, stamp_s: float, image=None, regions=None, *, image_msg=None, info_msg=None, regions_msg=None,
             grid=GRID):
        ns = int(round(stamp_s * 1e9))
        self.pub_info.publish(info_msg if info_msg is not None else grid_to_map_info(grid, ns))
        self.pub_image.publish(image_msg if image_msg is not None else
                               ma.array_to_image(image, '32FC1', stamp_ns=ns, frame_id='world'))
        self.pub_regions.publish(regions_msg if regions_msg is not None else
                                 ma.array_to_cloud(regions if regions is not None else np.zeros(0, ma.REGION_DTYPE),
                                                   stamp_ns=ns, frame_id='world'))

    def wait_tracks(self, n, timeout=30.0):
        try:
            self.ros.wait(lambda: len(self.tracks) >= n, timeout, f'{n} /gpf/tracks messages')
        except AssertionError as exc:
            raise AssertionError(f'{exc}; got {len(self.tracks)}; the node said: {self.stop()[-3000:]}') from None

    def stop(self) -> str:
        """SIGINT the node; its stderr (the log)."""
        return self.launch.stop(self.proc)

    def close(self):
        for s in self.subs:
            self.ros.node.destroy_subscription(s)
        for p in (self.pub_info, self.pub_image, self.pub_regions):
            self.ros.node.destroy_publisher(p)


@pytest.fixture
def tracker(ros, launch, request):
    proc = launch('gpf_tracker', *getattr(request, 'param', ()))
    h = Harness(ros, launch, proc)
    yield h
    h.close()


def path(k: int) -> tuple[float, float]:
    """A target crossing the image at 0.25 m/s along x, 5 s frames."""
    return 6.0 + 1.25 * k, 0.5


def test_tracks_a_target_through_an_empty_image_and_a_frame_without_regions(tracker):
    rng = np.random.default_rng(1)
    n = 12
    for k in range(n):
        xy = path(k)
        if k == 6:
            tracker.send(5.0 * k, np.zeros(GRID.shape, np.float32))     # no data at all
        elif k == 7:
            tracker.send(5.0 * k, synthetic_frame(rng, xy))            # echo but no region
        else:
            tracker.send(5.0 * k, synthetic_frame(rng, xy), regions_at(xy))
    tracker.wait_tracks(n)
    stamps = [ma.header_ns(m) for m in tracker.tracks]
    assert stamps == [int(5e9 * k) for k in range(n)]
    recs = [ma.cloud_to_array(m) for m in tracker.tracks]
    assert all(r.dtype == ma.GPF_TRACK_DTYPE for r in recs)
    # One confirmed track from the second frame on, with the same id through frames 6 and 7.
    ids = [set(r['track_id'][r['confirmed'] == 1].tolist()) for r in recs]
    assert all(len(i) == 1 for i in ids[1:]) and len(set.union(*ids[1:])) == 1, ids
    for k in (5, 6, 7, 8, n - 1):
        r = recs[k][recs[k]['confirmed'] == 1][0]
        assert math.hypot(r['x'] - path(k)[0], r['y'] - path(k)[1]) < 0.6, (k, r)
        assert all(math.isfinite(r[f]) for f in ma.GPF_TRACK_DTYPE.names)
    last = recs[-1][0]
    assert abs(last['vx'] - 0.25) < 0.12 and abs(last['vy']) < 0.12 and last['fusion'] in (0, 1)
    # Markers in the gpf namespace, and diagnostics that saw the empty image.
    tracker.ros.wait(lambda: len(tracker.markers) >= n, 20.0, 'markers')
    assert tracker.markers[-1].markers[0].action == 3
    assert {m.ns for m in tracker.markers[-1].markers[1:]} >= {'gpf/position', 'gpf/covariance'}
    tracker.ros.wait(lambda: any(dict((kv.key, kv.value) for kv in s.values).get('frames') == str(n)
                                 for s in tracker.diagnostics), 10.0, 'diagnostics after all frames')
    values = dict((kv.key, kv.value) for kv in tracker.diagnostics[-1].values)
    assert values['confirmed'] == '1' and float(values['latency_median_ms']) > 0
    err = tracker.stop()
    assert 'holds no data' in err


def test_no_target_gives_empty_tracks_messages(tracker):
    rng = np.random.default_rng(2)
    tracker.send(1.0, synthetic_frame(rng, None))
    tracker.wait_tracks(1)
    assert tracker.tracks[0].width == 0 and len(tracker.tracks[0].fields) == len(ma.GPF_TRACK_DTYPE.names)


@pytest.mark.parametrize('tracker', [('particles:=5', 'fusion.mode:=best', 'lost.max_time:=40.0')], indirect=True)
def test_parameters_refuse_bad_values_with_a_reason_and_apply_good_ones(tracker):
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.parameter import Parameter
    ros = tracker.ros
    setc = ros.node.create_client(SetParameters, '/gpf_tracker/set_parameters')
    getc = ros.node.create_client(GetParameters, '/gpf_tracker/get_parameters')
    assert setc.wait_for_service(timeout_sec=20.0) and getc.wait_for_service(timeout_sec=20.0)

    def set_(name, value):
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        return ros.call(setc, req).results[0]

    def get(*names):
        res = ros.call(getc, GetParameters.Request(names=list(names))).values
        return [v.integer_value if v.type == 2 else v.double_value if v.type == 3 else v.string_value
                if v.type == 4 else list(v.double_array_value) for v in res]

    assert get('particles', 'fusion.mode', 'lost.max_time', 'cues.features') == [300, 'af', 40.0,
                                                                                 [20.0, 17.0, 3.0, 6.0, 24.0]]
    r = set_('fusion.mode', 'sum')
    assert not r.successful and 'fusion.mode' in r.reason
    r = set_('cues.features', [3.0, 1.0])
    assert not r.successful and 'same for every window' in r.reason
    r = set_('fusion.thresholds', [1.0, 2.0])
    assert not r.successful and 'one or 5' in r.reason
    r = set_('seed', 4)
    assert not r.successful and 'read-only' in r.reason
    assert set_('fusion.mode', 'wf').successful
    assert set_('cues.features', [3.0, 24.0]).successful
    rng = np.random.default_rng(5)
    for k in range(3):
        tracker.send(5.0 * k, synthetic_frame(rng, path(k)), regions_at(path(k)))
    tracker.wait_tracks(3)
    assert ma.cloud_to_array(tracker.tracks[-1])['fusion'][0] in (0, 1)
    err = tracker.stop()
    assert 'particles' in err and 'fusion.mode' in err
    ros.node.destroy_client(setc)
    ros.node.destroy_client(getc)


def test_tracks_targets_from_the_simulated_sonar_through_fls_features(ros, launch):
    """The whole FLS chain: seaking_sim (Table 5 situation 4, one reflector towed toward the sonar) ->
    fls_features -> gpf_tracker; a confirmed track follows the target as imaged."""
    from sensor_msgs.msg import Image, LaserScan, PointCloud2
    tracks, truth = [], []
    # The probe also reads the sectors, so the simulator (wait_for_subscribers 2) starts only once it
    # has matched this process's readers: the truth of the first sectors is not lost to discovery.
    subs = [ros.node.create_subscription(PointCloud2, '/gpf/tracks', tracks.append, KEEP_ALL),
            ros.node.create_subscription(PointCloud2, '/sonar/truth', truth.append, KEEP_ALL),
            ros.node.create_subscription(Image, '/sonar/sector', lambda m: None, 10),
            ros.node.create_subscription(LaserScan, '/sonar/sector_info', lambda m: None, 10)]
    launch('gpf_tracker', params_file=CONFIG)
    launch('fls_features')
    # Regions reach the tracker and its tracks reach us (graph entries of earlier tests' nodes would not say so).
    ros.wait_listened([('fls_features: segmentation', '/fls/regions'), ('gpf_tracker: tracking', '/gpf/tracks')])
    sim = launch('seaking_sim', 'scenario:=fls4', 'seed:=3', 'duration:=40.2', 'rate:=0.0', 'wait_for_subscribers:=2',
                 'shutdown_when_done:=true')
    ros.wait(lambda: sim.poll() is not None, 90.0, 'the simulator to finish')
    ros.wait(lambda: len(tracks) >= 7, 20.0, 'tracks of every frame')
    for s in subs:
        ros.node.destroy_subscription(s)
    path_xy = np.array([(t['x'], t['y']) for m in truth for t in ma.cloud_to_array(m)])
    last = ma.cloud_to_array(tracks[-1])
    conf = last[last['confirmed'] == 1]
    assert len(conf) >= 1, [ma.cloud_to_array(m) for m in tracks]
    # Within a metre of where the target passed during the last sweep.
    d = np.hypot(path_xy[-300:, 0] - conf['x'][0], path_xy[-300:, 1] - conf['y'][0]).min()
    assert d < 1.0, d
