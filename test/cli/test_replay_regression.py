"""Replay regression: a simulator bag through active_detector and imm_ipda_tracker over DDS equals the
same bag through the core in-process, run after run, and again after ``--repeat`` wraps time back."""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

import sonar_tracking.msgs as ma
from sonar_tracking import process
from sonar_tracking.core.detection import ActiveDetector
from sonar_tracking.core.tracking import ImmIpdaTracker
from sonar_tracking.core.tracking.detections import detections_to_measurements
from sonar_tracking.io.bags import bag_topics, read_bag
from sonar_tracking.nodes.active_detector import DetectorNodeConfig
from sonar_tracking.nodes.imm_ipda_tracker import TrackerNodeConfig

pytestmark = pytest.mark.ros

CONFIG = Path(__file__).resolve().parents[2] / 'config'
SONAR_POSE = '[-2000.0, 0.0, 0.0]'
KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
SCANS = 30


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """A short Scenario 1 bag made here from the simulator."""
    import yaml
    path = tmp_path_factory.mktemp('replay') / 'scenario1'
    topics = ['/sonar/sector', '/sonar/sector_info', '/sonar/truth', '/platform/odometry']
    rec = subprocess.Popen([sys.executable, '-m', 'sonar_tracking.cli.bag_record', '-o', str(path), *topics],
                           stderr=subprocess.PIPE, text=True, preexec_fn=process.child_dies_with_parent())
    # The simulator waits for a subscriber (the recorder subscribes to the package's topics at once).
    sim = subprocess.run([sys.executable, '-m', 'sonar_tracking.nodes.seaking_sim', '--ros-args', '-p',
                          'scenario:=scenario1', '-p', 'rate:=0.0', '-p', f'duration:={SCANS}.0', '-p',
                          'wait_for_subscribers:=1', '-p', 'shutdown_when_done:=true'], capture_output=True,
                         text=True, timeout=120)
    assert sim.returncode == 0, sim.stderr

    def on_disk():   # the recorder rewrites the metadata at every flush
        try:
            return yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']['message_count']
        except (OSError, KeyError, TypeError, yaml.YAMLError):
            return 0
    deadline = time.monotonic() + 20.0
    while on_disk() < 4 * SCANS and time.monotonic() < deadline:
        time.sleep(0.05)
    rec.send_signal(2)
    rec.communicate(timeout=20)
    assert sum(1 for m in read_bag(path) if m.topic == '/sonar/sector') == SCANS
    return path


def core_tracks(bag: Path) -> list[tuple[int, np.ndarray]]:
    """The bag through the core, as the two nodes process it: ``[(stamp_ns, tracks), ...]`` (the tracks the
    node publishes: confirmed ones unless ``publish_tentative``)."""
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {t.name: t.msgtype for t in bag_topics(bag)}
    det_cfg = DetectorNodeConfig.from_flat({'sonar_pose': (-2000.0, 0.0, 0.0)})
    det = ActiveDetector(det_cfg, det_cfg.esc.desired_clutter_density)
    params = _tracker_params()
    trk = ImmIpdaTracker(TrackerNodeConfig.from_flat(params))
    pairer = ma.SectorPairer()
    out, origin = [], None
    for m in read_bag(bag, ['/sonar/sector', '/sonar/sector_info']):
        msg = store.deserialize_cdr(m.data, types[m.topic])
        pair = (pairer.add_image if m.topic == '/sonar/sector' else pairer.add_info)(msg)
        if pair is None:
            continue
        amps, geom = ma.sector_from_messages(pair.image, pair.info)
        result = det.process(amps, geom, (-2000.0, 0.0, 0.0))
        records = np.frombuffer(ma.array_to_cloud(result.detections).data, dtype=np.uint8).view(ma.DETECTION_DTYPE)
        z, R, rho, _ = detections_to_measurements(records)
        origin = pair.stamp_ns if origin is None else origin
        tracks = trk.step((pair.stamp_ns - origin) * 1e-9, z, R, rho)
        out.append((pair.stamp_ns, tracks if params['publish_tentative'] else tracks[tracks['confirmed'] != 0]))
    return out


def _tracker_params() -> dict:
    from sonar_tracking.io import param_files
    return param_files.parameters_for(param_files.load(CONFIG / 'imm_ipda.yaml'), 'imm_ipda_tracker')


def node_tracks(ros, launch, bag: Path, repeat: int = 1) -> list[tuple[int, np.ndarray]]:
    """The bag replayed (``--fast``) through the two nodes; ``/tracks`` as received."""
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import PointCloud2
    got = []
    sub = ros.node.create_subscription(PointCloud2, '/tracks', got.append, KEEP_ALL, raw=True)
    nodes = [launch('imm_ipda_tracker', params_file=CONFIG / 'imm_ipda.yaml'),
             launch('active_detector', f'sonar_pose:={SONAR_POSE}', 'esc.density_source:=sector')]
    try:
        # Detections reach the tracker and tracks reach us: both writers report a matched reader.
        ros.wait_listened([('active_detector: detection', '/detections'), ('imm_ipda_tracker: tracking', '/tracks')])
        replay = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.bag_replay', str(bag), '--fast',
                                 '--repeat', str(repeat), '--topics', '/sonar/sector', '/sonar/sector_info',
                                 '--wait-for', '/sonar/sector', '/sonar/sector_info'],
                                capture_output=True, text=True, timeout=120)
        assert replay.returncode == 0, replay.stderr
        try:
            ros.wait(lambda: len(got) >= SCANS * repeat, 30.0, f'{SCANS * repeat} /tracks messages')
        except AssertionError as e:     # say what arrived and what the nodes logged
            logs = '\n'.join(launch.stop(p) for p in nodes)
            raise AssertionError(f'{e}: {len(got)} arrived; replay: {replay.stderr}\nnodes:\n{logs}') from None
        for proc in nodes:
            assert proc.poll() is None, proc.stderr.read()
    finally:
        ros.node.destroy_subscription(sub)
        for proc in nodes:   # the next replay must meet fresh nodes only
            launch.stop(proc)
        ros.wait(lambda: ros.node.count_publishers('/tracks') == 0 and ros.node.count_publishers('/detections') == 0,
                 20.0, 'the stopped nodes to leave the graph')
    msgs = [deserialize_message(bytes(g), PointCloud2) for g in got]
    return [(ma.header_ns(m), np.array(ma.cloud_to_array(m))) for m in msgs]


def renumber(run: list[tuple[int, np.ndarray]]) -> list[tuple[int, np.ndarray]]:
    """Track ids counted from 1 in order of appearance (ids keep counting across a reset)."""
    first: dict[int, int] = {}
    out = []
    for stamp, tracks in run:
        t = tracks.copy()
        for i, tid in enumerate(t['track_id'].tolist()):
            t['track_id'][i] = first.setdefault(tid, len(first) + 1)
        out.append((stamp, t))
    return out


def same(a, b) -> bool:
    return len(a) == len(b) and all(sa == sb and np.array_equal(ta, tb) for (sa, ta), (sb, tb) in zip(a, b))


def test_nodes_equal_core_and_replays_are_deterministic(ros, launch, bag):
    core = core_tracks(bag)
    assert len(core) == SCANS and any(t['confirmed'].any() for _, t in core)
    first = node_tracks(ros, launch, bag)
    assert same(first, core)
    second = node_tracks(ros, launch, bag)
    assert same(second, first)


def test_a_wrapped_replay_repeats_the_tracks(ros, launch, bag):
    looped = node_tracks(ros, launch, bag, repeat=2)
    assert len(looped) == 2 * SCANS
    passes = renumber(looped[:SCANS]), renumber(looped[SCANS:])
    assert same(*passes)
    # The second pass's ids are new ones: never reused within the tracker's life.
    ids_1 = {int(i) for _, t in looped[:SCANS] for i in t['track_id']}
    ids_2 = {int(i) for _, t in looped[SCANS:] for i in t['track_id']}
    assert not ids_1 & ids_2
