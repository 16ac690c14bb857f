"""The seaking_sim node over real DDS: determinism, topics, parameters good and bad."""
from __future__ import annotations

import os
import re
import signal
import subprocess

import numpy as np
import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

import sonar_tracking.msgs as ma

pytestmark = pytest.mark.ros

KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)


def record(ros, proc: subprocess.Popen, topics: dict, raw: bool, timeout: float = 60.0) -> tuple[dict, str]:
    """Subscribe to ``{topic: type}``, collect until ``proc`` exits and every sector it says it published
    has arrived on every topic; ``(messages by topic, the simulator's log)``."""
    got = {t: [] for t in topics}
    subs = [ros.node.create_subscription(typ, t, got[t].append, KEEP_ALL, raw=raw) for t, typ in topics.items()]
    try:
        ros.wait(lambda: proc.poll() is not None, timeout, 'the simulator to finish')
        err = proc.stderr.read()
        sent = re.search(r'finished after (\d+) sectors', err)
        assert sent, err
        ros.wait(lambda: all(len(m) >= int(sent.group(1)) for m in got.values()), 20.0, 'every published sector')
    finally:
        for s in subs:
            ros.node.destroy_subscription(s)
    return got, err


def sim_topics():
    from sensor_msgs.msg import Image, LaserScan, PointCloud2
    return {'/sonar/sector': Image, '/sonar/sector_info': LaserScan, '/sonar/truth': PointCloud2}


def test_same_seed_same_messages_bit_for_bit(ros, launch):
    runs = []
    for _ in range(2):
        proc = launch('seaking_sim', 'scenario:=fls9', 'seed:=3', 'duration:=3.0', 'rate:=0.0',
                      'wait_for_subscribers:=1', 'shutdown_when_done:=true')
        got, err = record(ros, proc, sim_topics(), raw=True)
        runs.append(got)
        assert proc.returncode == 0, err
    a, b = runs
    # 3 s of pings at 50 ms, 10 per sector.
    assert len(a['/sonar/sector']) == 6
    for topic in a:
        assert len(a[topic]) == len(b[topic]) > 0
        assert a[topic] == b[topic], topic


def test_publishes_paired_sectors_truth_and_odometry(ros, launch):
    from nav_msgs.msg import Odometry
    topics = sim_topics() | {'/platform/odometry': Odometry}
    proc = launch('seaking_sim', 'scenario:=sea_trial', 'duration:=4.0', 'rate:=0.0', 'wait_for_subscribers:=1',
                  'shutdown_when_done:=true', 'sector_size:=13')
    got, _ = record(ros, proc, topics, raw=False)
    assert len(got['/sonar/sector']) == len(got['/sonar/sector_info']) == len(got['/sonar/truth']) > 2
    for img, scan, truth in zip(got['/sonar/sector'], got['/sonar/sector_info'], got['/sonar/truth']):
        amps, geom = ma.sector_from_messages(img, scan)
        assert img.encoding == '32FC1' and img.header.frame_id == 'sonar' and truth.header.frame_id == 'world'
        assert amps.shape == (600, geom.n_beams) and geom.n_beams <= 13
        assert ma.header_ns(truth) == ma.header_ns(img)
        assert sorted(ma.cloud_to_array(truth)['target_id']) == [1, 2]
    # The AUV moves at 0.5 m/s along x.
    poses = [(ma.header_ns(m) / 1e9, ma.odometry_to_pose(m)) for m in got['/platform/odometry']]
    assert len(poses) >= 3
    for t, (x, y, yaw) in poses:
        assert (x, y, yaw) == pytest.approx((0.5 * t, 0.0, 0.0), abs=1e-6)


def test_parameter_file_from_config(ros, launch):
    from pathlib import Path
    path = Path(__file__).resolve().parents[2] / 'config' / 'sim_seaking325.yaml'
    proc = launch('seaking_sim', 'rate:=0.0', 'duration:=2.0', 'wait_for_subscribers:=1', 'shutdown_when_done:=true',
                  params_file=path)
    got, err = record(ros, proc, sim_topics(), raw=False)
    amps, geom = ma.sector_from_messages(got['/sonar/sector'][0], got['/sonar/sector_info'][0])
    # 325 kHz, 50 m, 1.8 deg steps, 20 pings per sector, continuous turn.
    assert geom.angle_increment == pytest.approx(np.radians(1.8), rel=1e-6) and geom.n_beams == 20
    assert geom.range_max == pytest.approx(50.0 - 50.0 / 1200, rel=1e-4)
    assert geom.ping_period == pytest.approx(2 * 50.0 / 1500.0 + 0.01, rel=1e-6)
    assert 'SeaKing 325 kHz' in err


def test_bad_startup_parameters_are_refused_and_the_node_keeps_running(ros, launch):
    proc = launch('seaking_sim', 'scenario:=fls3', 'preset:=seaking999', 'seaking.range_max:=-5.0',
                  'seaking.n_bins:=0', 'rate:=0.0', 'duration:=1.0', 'wait_for_subscribers:=1',
                  'shutdown_when_done:=true')
    got, err = record(ros, proc, sim_topics(), raw=False)
    assert "preset = 'seaking999' is not one of" in err
    assert 'seaking.range_max' in err and 'seaking.n_bins' in err
    assert got['/sonar/sector'], err
    amps, geom = ma.sector_from_messages(got['/sonar/sector'][0], got['/sonar/sector_info'][0])
    assert geom.n_bins == 600 and geom.range_max == pytest.approx(30.0 - 0.025, abs=1e-3)


def test_runtime_parameter_changes_refused_with_reason_or_applied(ros, launch):
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter
    launch('seaking_sim', 'scenario:=fls3', 'rate:=1.0')
    client = ros.node.create_client(SetParameters, '/seaking_sim/set_parameters')
    assert client.wait_for_service(timeout_sec=20.0)

    def set_(name, value):
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        return ros.call(client, req).results[0]

    r = set_('clutter_lambda', -1.0)
    assert not r.successful and 'clutter_lambda' in r.reason
    r = set_('seaking.range_max', 50.0)
    assert not r.successful and 'read-only' in r.reason
    r = set_('preset', 'seaking325')
    assert not r.successful and 'read-only' in r.reason
    r = set_('snr_db', 'loud')
    assert not r.successful
    assert set_('snr_db', 30.0).successful
    assert set_('rate', 3.0).successful
    assert set_('clutter_lambda', 2).successful  # an integer for a double is accepted
    # Still publishing after all that.
    from sensor_msgs.msg import Image
    got = []
    sub = ros.node.create_subscription(Image, '/sonar/sector', got.append, 10)
    ros.wait(lambda: len(got) >= 2, 20.0, 'sectors after the parameter changes')
    ros.node.destroy_subscription(sub)
    assert np.isfinite(ma.image_to_array(got[-1])).all()


def test_fan_image_shows_the_target_where_truth_says(ros, launch):
    """The node's /sonar/fan: the brightest spot after a sweep sits on the truth (within half a metre)."""
    from sensor_msgs.msg import Image, LaserScan, PointCloud2

    from sonar_tracking.core.fan import PolarCanvas
    from sonar_tracking.sim import SeaKingSonar, SimConfig
    fans, truths = [], []
    subs = [ros.node.create_subscription(Image, '/sonar/fan', fans.append, KEEP_ALL),
            ros.node.create_subscription(PointCloud2, '/sonar/truth', truths.append, KEEP_ALL),
            ros.node.create_subscription(Image, '/sonar/sector', lambda m: None, KEEP_ALL),
            ros.node.create_subscription(LaserScan, '/sonar/sector_info', lambda m: None, KEEP_ALL)]
    proc = launch('seaking_sim', 'scenario:=fls14', 'snr_db:=40.0', 'duration:=5.2', 'rate:=0.0', 'fan_size:=600',
                  'wait_for_subscribers:=1', 'shutdown_when_done:=true')
    ros.wait(lambda: proc.poll() is not None, 60.0, 'the simulator to finish')
    err = proc.stderr.read()
    sent = int(re.search(r'finished after (\d+) sectors', err).group(1))
    ros.wait(lambda: len(truths) >= sent and fans and ma.header_ns(fans[-1]) == ma.header_ns(truths[-1]), 20.0,
             'the fan of the last sector')
    for s in subs:
        ros.node.destroy_subscription(s)
    # The canvas the node paints into, rebuilt from the same configuration.
    cfg = SimConfig.for_scenario('fls14')
    canvas = PolarCanvas.with_size(SeaKingSonar(cfg.seaking, cfg.sector_size).coverage(), 600)
    img = ma.image_to_array(fans[-1])
    assert img.shape == canvas.image.shape and img.dtype == np.uint8
    row, col = np.unravel_index(np.argmax(img), img.shape)
    x, y = canvas.point_of(row, col)
    truth = ma.cloud_to_array(truths[-1])[0]
    assert np.hypot(x - truth['x'], y - truth['y']) < 0.5


def test_diagnostics_say_rate_scenario_clock_subscribers_and_the_end(ros, inproc):
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    from sonar_tracking.nodes.seaking_sim import SeaKingSimNode
    reports = []
    subs = [ros.node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: reports.extend(
                s for s in m.status if s.name == 'seaking_sim: simulation'), KEEP_ALL)]
    subs += [ros.node.create_subscription(t, n, lambda m: None, KEEP_ALL) for n, t in sim_topics().items()]
    try:
        sim = inproc(SeaKingSimNode, scenario='fls3', duration=3.0, rate=0.0, wait_for_subscribers=1)
        ros.wait(lambda: any('finished after' in s.message for s in reports), 60.0, 'the report of the end')
        end = next(s for s in reports if 'finished after' in s.message)
        values = {kv.key: kv.value for kv in end.values}
        assert end.level == DiagnosticStatus.OK and end.message.startswith('scenario fls3 finished after')
        assert values['sectors'] == values['processed'] == str(sim.sectors) and sim.sectors > 3
        assert float(values['rate_hz']) > 0.0 and float(values['sim_time_s']) <= 3.0
        assert (values['scenario'], values['clock'], values['stamps']) == ('fls3', 'off', 'sim')
        assert int(values['subscribers /sonar/sector']) >= 1 and 'subscribers /sonar/fan' in values
        started = [s for s in reports if {kv.key: kv.value for kv in s.values}.get('sectors') == '1']
        assert started and started[0].level == DiagnosticStatus.OK, 'a report when the first sector went out'
    finally:
        for s in subs:
            ros.node.destroy_subscription(s)



def test_projected_frames_give_the_adapter_the_simulators_sectors(ros, launch):
    """publish_projected: every sector also goes out as a ProjectedSonarImage, and
    projected_sonar_adapter (in a namespace of its own) turns each back into the same sector."""
    pytest.importorskip('marine_acoustic_msgs.msg', reason='marine_acoustic_msgs not built here (make build does)')
    import sys

    from sensor_msgs.msg import Image, LaserScan

    from sonar_tracking import process
    adapter = subprocess.Popen([sys.executable, '-m', 'sonar_tracking.nodes.projected_sonar_adapter', '--ros-args',
                                '-r', '__ns:=/adapted', '-r', 'sonar_image:=/sonar_image'], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, start_new_session=True,
                               preexec_fn=process.child_dies_with_parent())
    try:
        ros.wait(lambda: ros.node.count_subscribers('/sonar_image') >= 1, 60.0, 'the adapter to subscribe')
        got = {t: [] for t in ('/sonar/sector', '/sonar/sector_info', '/adapted/sonar/sector',
                                '/adapted/sonar/sector_info')}
        for topic in got:
            ros.node.create_subscription(Image if topic.endswith('sector') else LaserScan, topic, got[topic].append,
                                         KEEP_ALL)
        ros.wait(lambda: ros.node.count_publishers('/adapted/sonar/sector') >= 1, 30.0, 'the adapter\'s output')
        proc = launch('seaking_sim', 'scenario:=imaging_diver', 'preset:=aris3000', 'duration:=0.5', 'rate:=0.0',
                      'wait_for_subscribers:=1', 'shutdown_when_done:=true', 'publish_projected:=true')
        ros.wait(lambda: proc.poll() is not None, 60.0, 'the simulator to finish')
        sent = int(re.search(r'finished after (\d+) sectors', proc.stderr.read()).group(1))
        ros.wait(lambda: min(len(m) for m in got.values()) >= sent, 30.0, 'every sector through the adapter')
    finally:
        os.killpg(adapter.pid, signal.SIGINT)
        adapter.communicate(timeout=30)
    assert sent >= 2
    for img, scan, a_img, a_scan in zip(*got.values()):
        values, geometry = ma.sector_from_messages(img, scan)
        a_values, a_geometry = ma.sector_from_messages(a_img, a_scan)
        assert ma.header_ns(a_img) == ma.header_ns(img) and a_img.encoding == img.encoding == 'mono8'
        np.testing.assert_array_equal(a_values, values)
        assert a_geometry.angle_min == pytest.approx(geometry.angle_min, abs=1e-6)
        assert a_geometry.angle_increment == pytest.approx(geometry.angle_increment, rel=1e-5)
        assert a_geometry.range_min == pytest.approx(geometry.range_min, rel=1e-5)
        assert a_geometry.range_max == pytest.approx(geometry.range_max, rel=1e-5)
