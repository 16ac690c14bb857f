"""bag_record and bag_replay over real DDS; bag metadata; reading bags that were cut off."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest
import yaml
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from sonar_tracking.tools.bags import TruncatedBagWarning, bag_topics, read_bag

pytestmark = pytest.mark.ros

SIM_TOPICS = ['/sonar/sector', '/sonar/sector_info', '/sonar/truth', '/platform/odometry']


def tool(module, *args):
    return subprocess.Popen([sys.executable, '-m', f'sonar_tracking.tools.{module}', *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)


def stop(proc, timeout=15):
    os.killpg(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=timeout)
    assert proc.returncode == 0, err
    return out, err


def wait_recording(rec, topics, timeout=20.0):
    """Wait until bag_record says it records every topic (it logs to stderr)."""
    seen, lines = set(), []
    deadline = time.monotonic() + timeout
    os.set_blocking(rec.stderr.fileno(), False)
    while time.monotonic() < deadline and not set(topics) <= seen:
        line = rec.stderr.readline()
        if line:
            lines.append(line)
            m = re.search(r'recording (\S+)', line)
            if m:
                seen.add(m.group(1))
        else:
            time.sleep(0.05)
    os.set_blocking(rec.stderr.fileno(), True)
    assert set(topics) <= seen, ''.join(lines)


def record_sim(tmp_path, launch, name, sim_params, storage='mcap', topics=SIM_TOPICS, timeout=120):
    """Record a simulator run; returns (bag path, sectors the simulator says it published)."""
    bag = tmp_path / name
    rec = tool('bag_record', '-o', str(bag), '--storage', storage, *topics)
    sim = launch('seaking_sim', *sim_params, 'shutdown_when_done:=true')
    wait_recording(rec, topics)
    sim.wait(timeout)
    err = sim.stderr.read()
    n = int(re.search(r'finished after (\d+) sectors', err).group(1))
    time.sleep(1.0)
    stop(rec)
    return bag, n


@pytest.mark.slow
def test_nothing_lost_at_50_hz_for_60_s(tmp_path, launch):
    # 7.5 m range, 10 ms processing: a ping every 20 ms; one ping per sector: 50 sectors/s.
    bag, n = record_sim(tmp_path, launch, 'fast', ['scenario:=fls1', 'sector_size:=1', 'seaking.range_max:=7.5',
                                                   'seaking.n_bins:=150', 'rate:=1.0', 'duration:=60.0',
                                                   'wait_for_subscribers:=1'], timeout=120)
    assert n == 3000
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    counts = {t['topic_metadata']['name']: t['message_count'] for t in meta['topics_with_message_count']}
    assert counts == {t: n for t in SIM_TOPICS}
    assert sum(1 for _ in read_bag(bag, ['/sonar/sector'])) == n


def test_metadata_is_rosbag2_version_8_with_qos(tmp_path, launch):
    bag, n = record_sim(tmp_path, launch, 'meta', ['scenario:=scenario1', 'rate:=0.0', 'duration:=5.0',
                                                   'wait_for_subscribers:=1'])
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    # The fields ROS 2 Jazzy's metadata reader (version 8) expects.
    assert info['version'] == 8 and info['storage_identifier'] == 'mcap'
    assert set(info) >= {'relative_file_paths', 'duration', 'starting_time', 'message_count',
                         'topics_with_message_count', 'compression_format', 'compression_mode', 'files'}
    assert info['message_count'] == 4 * n == sum(t['message_count'] for t in info['topics_with_message_count'])
    for t in info['topics_with_message_count']:
        md = t['topic_metadata']
        assert set(md) >= {'name', 'type', 'serialization_format', 'offered_qos_profiles', 'type_description_hash'}
        assert md['type_description_hash'].startswith('RIHS01_')
        qos = yaml.safe_load(md['offered_qos_profiles'])
        assert qos and qos[0]['reliability'] == 1  # the simulator publishes reliably
    types = {t.name: t.msgtype for t in bag_topics(bag)}
    assert types['/sonar/sector'] == 'sensor_msgs/msg/Image'


def test_sqlite3_storage(tmp_path, launch):
    bag, n = record_sim(tmp_path, launch, 'sql', ['scenario:=scenario1', 'rate:=0.0', 'duration:=3.0',
                                                  'wait_for_subscribers:=1'], storage='sqlite3')
    assert list(bag.glob('*.db3'))
    assert sum(1 for m in read_bag(bag) if m.topic == '/sonar/sector') == n


def test_latched_topic_recorded_as_transient_local(tmp_path, ros):
    from std_msgs.msg import Float64
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
    pub = ros.node.create_publisher(Float64, '/test_latched', latched)
    pub.publish(Float64(data=4.5))      # before the recorder exists: only transient local catches it
    bag = tmp_path / 'latched'
    rec = tool('bag_record', '-o', str(bag), '/test_latched')
    wait_recording(rec, ['/test_latched'])
    time.sleep(1.0)
    stop(rec)
    ros.node.destroy_publisher(pub)
    (topic,) = bag_topics(bag)
    assert topic.qos[0].durability.name == 'TRANSIENT_LOCAL'
    msgs = list(read_bag(bag))
    assert len(msgs) == 1


def test_cut_off_bag_is_read_up_to_the_cut_with_a_warning(tmp_path, launch):
    bag, n = record_sim(tmp_path, launch, 'cut', ['scenario:=fls2', 'rate:=0.0', 'duration:=20.0',
                                                  'wait_for_subscribers:=1'])
    full = list(read_bag(bag))
    (mcap,) = bag.glob('*.mcap')
    size = mcap.stat().st_size
    os.truncate(mcap, int(size * 0.7))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        cut = list(read_bag(bag))
    msgs = [str(w.message) for w in caught if issubclass(w.category, TruncatedBagWarning)]
    assert msgs and 'cut off' in msgs[0] and f'read the {len(cut)} messages' in msgs[0]
    assert 0.4 * len(full) < len(cut) < len(full)
    assert [(m.topic, m.timestamp, m.data) for m in cut] == [(m.topic, m.timestamp, m.data) for m in full[:len(cut)]]


def test_replay_fast_sends_everything_in_order_and_repeat_loops(tmp_path, launch, ros):
    from sensor_msgs.msg import Image, LaserScan
    bag, n = record_sim(tmp_path, launch, 'replay', ['scenario:=scenario1', 'rate:=0.0', 'duration:=6.0',
                                                     'wait_for_subscribers:=1'])
    recorded = [m.data for m in read_bag(bag, ['/sonar/sector'])]
    keep_all = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    got = []
    subs = [ros.node.create_subscription(Image, '/sonar/sector', got.append, keep_all, raw=True),
            ros.node.create_subscription(LaserScan, '/sonar/sector_info', lambda m: None, keep_all)]
    rep = tool('bag_replay', str(bag), '--fast', '--repeat', '2', '--topics', '/sonar/sector', '/sonar/sector_info',
               '--wait-for', '/sonar/sector', '/sonar/sector_info')
    rep.wait(60)
    ros.wait(lambda: len(got) >= 2 * n, 20.0, 'the replayed sectors')
    for s in subs:
        ros.node.destroy_subscription(s)
    assert rep.returncode == 0, rep.stderr.read()
    assert [bytes(g) for g in got] == recorded * 2
    assert 'replayed 24 messages in 2 pass(es)' in rep.stderr.read()


def test_replay_keeps_the_recorded_spacing(tmp_path, launch, ros):
    from sensor_msgs.msg import Image
    bag, n = record_sim(tmp_path, launch, 'timed', ['scenario:=scenario1', 'rate:=4.0', 'duration:=6.0',
                                                    'wait_for_subscribers:=1'], topics=['/sonar/sector',
                                                                                        '/sonar/sector_info',
                                                                                        '/sonar/truth'])
    stamps = [m.timestamp for m in read_bag(bag, ['/sonar/sector'])]
    arrivals = []
    sub = ros.node.create_subscription(Image, '/sonar/sector', lambda m: arrivals.append(time.monotonic()),
                                       QoSProfile(history=HistoryPolicy.KEEP_ALL,
                                                  reliability=ReliabilityPolicy.RELIABLE), raw=True)
    rep = tool('bag_replay', str(bag), '--rate', '2.0', '--topics', '/sonar/sector', '--wait-for', '/sonar/sector')
    rep.wait(60)
    ros.wait(lambda: len(arrivals) >= n, 10.0, 'the replayed sectors')
    ros.node.destroy_subscription(sub)
    recorded = np.diff(stamps) / 1e9
    replayed = np.diff(arrivals)
    # Recorded at 4x real time (0.25 s apart), replayed at rate 2: 0.125 s apart.
    assert np.median(replayed) == pytest.approx(np.median(recorded) / 2, rel=0.15)
