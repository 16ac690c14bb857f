"""bag_record and bag_replay over real DDS; bag metadata; recordings killed with SIGKILL or ended by a
full disk; reading bags that were cut off."""
from __future__ import annotations

import contextlib
import os
import re
import resource
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest
import yaml
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from sonar_tracking import process
from sonar_tracking.io.bags import TruncatedBagWarning, bag_topics, read_bag

pytestmark = pytest.mark.ros

SIM_TOPICS = ['/sonar/sector', '/sonar/sector_info', '/sonar/truth', '/platform/odometry']


def tool(module, *args, preexec_fn=None, **kwargs):
    return subprocess.Popen([sys.executable, '-m', f'sonar_tracking.cli.{module}', *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=process.child_dies_with_parent(then=preexec_fn), **kwargs)


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
    try:
        sim = launch('seaking_sim', *sim_params, 'shutdown_when_done:=true')
        wait_recording(rec, topics)
        sim.wait(timeout)
        err = sim.stderr.read()
        finished = re.search(r'finished after (\d+) sectors', err)
        assert finished, err
        n = int(finished.group(1))
        # One message per sector on each topic: wait until the recorder has flushed them all.
        wait_until(lambda: on_disk(bag) >= len(topics) * n, 20.0, f'{len(topics) * n} messages in the bag')
    except BaseException:
        os.killpg(rec.pid, signal.SIGKILL)      # a failed test leaves no recorder behind
        rec.communicate(timeout=10)
        raise
    stop(rec)
    return bag, n


def wait_until(predicate, timeout, what):
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f'timed out after {timeout} s waiting for {what}'
        time.sleep(0.02)


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


def test_metadata_is_rosbag2_version_9_as_jazzy_writes_it(tmp_path, launch):
    bag, n = record_sim(tmp_path, launch, 'meta', ['scenario:=scenario1', 'rate:=0.0', 'duration:=5.0',
                                                   'wait_for_subscribers:=1'])
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    # The fields and forms of ROS 2 Jazzy's metadata (version 9): QoS profiles as a list of mappings
    # with lower-case policy names, ros_distro, custom_data.
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap' and info['ros_distro'] == 'jazzy'
    assert info['custom_data'] == {'recorder_state': 'closed'}
    assert list(info) == ['version', 'storage_identifier', 'duration', 'starting_time', 'message_count',
                          'topics_with_message_count', 'compression_format', 'compression_mode',
                          'relative_file_paths', 'files', 'custom_data', 'ros_distro']
    assert info['relative_file_paths'] == ['meta_0.mcap'] and [f['path'] for f in info['files']] == ['meta_0.mcap']
    assert info['message_count'] == 4 * n == sum(t['message_count'] for t in info['topics_with_message_count'])
    assert info['files'][0]['message_count'] == info['message_count']
    for t in info['topics_with_message_count']:
        md = t['topic_metadata']
        assert list(md) == ['name', 'type', 'serialization_format', 'offered_qos_profiles', 'type_description_hash']
        assert md['type_description_hash'].startswith('RIHS01_')
        (qos,) = md['offered_qos_profiles']
        assert qos['reliability'] == 'reliable' and qos['durability'] == 'volatile'   # the simulator's
    types = {t.name: t.msgtype for t in bag_topics(bag)}
    assert types['/sonar/sector'] == 'sensor_msgs/msg/Image'
    # rosbags reads it (it reads versions up to 9) with the same counts.
    from rosbags.rosbag2 import Reader
    with Reader(bag) as reader:
        assert reader.message_count == 4 * n


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
    wait_until(lambda: on_disk(bag) >= 1, 20.0, 'the latched message in the bag')
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
    assert 'File end magic is invalid' in msgs[0]    # why rosbags does not read it
    assert 'cut off at byte' in msgs[1] and f'read the {len(cut)} messages before the cut' in msgs[1]
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


# ---------------------------------------------------------------------- crashes and a full disk
class Counter:
    """A publisher of numbered images (``frame_id`` = number, stamp = wall time of publishing) on a timer
    of the test's node: every message's number and publish time are kept. The default history is 10 s:
    a reliable writer overwrites what a reader has not acknowledged yet, and with 1 s (depth 100) one
    of 20 recorders starved on a loaded CI machine lost message 913 in the middle of its 825-1,023."""

    def __init__(self, ros, topic, period=0.01, size=2000, depth=1000):
        from sensor_msgs.msg import Image
        self.msg = Image(height=1, width=size, encoding='mono8', step=size, data=bytes(size))
        self.pub = ros.node.create_publisher(Image, topic,
                                             QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE))
        self.times = []
        self.timer = ros.node.create_timer(period, self.publish)
        self.ros = ros

    def publish(self):
        self.msg.header.frame_id = str(len(self.times))
        now = time.time()
        self.msg.header.stamp.sec, self.msg.header.stamp.nanosec = int(now), int(now % 1 * 1e9)
        self.times.append(now)
        self.pub.publish(self.msg)

    @property
    def count(self):
        return len(self.times)

    def close(self):
        self.ros.node.destroy_timer(self.timer)
        self.ros.node.destroy_publisher(self.pub)


def numbers(bag, expect_warning=True):
    """Message numbers in a bag as read_bag (what bag_replay plays) gives them, and the warnings."""
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Image
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        got = [int(deserialize_message(m.data, Image).header.frame_id) for m in read_bag(bag)]
    said = [str(w.message) for w in caught if issubclass(w.category, TruncatedBagWarning)]
    assert bool(said) == expect_warning, said
    return got, said


def on_disk(bag):
    """Messages the bag's metadata counts (rewritten by the recorder at every flush); read with a
    pattern, not a YAML parser, to keep the polling light for the publisher in this process."""
    try:
        m = re.search(r'^  message_count: (\d+)$', (bag / 'metadata.yaml').read_text(), re.M)
    except OSError:
        return 0
    return int(m.group(1)) if m else 0


def readers_agree(bag, n):
    """rosbags and the mcap library read the same ``n`` messages (after ``bag_record --repair`` where needed)."""
    from rosbags.rosbag2 import Reader, ReaderError
    try:
        with Reader(bag) as reader:
            direct = sum(1 for _ in reader.messages())
    except ReaderError:
        direct = None
    if direct != n:
        rep = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.bag_record', '--repair', str(bag)],
                             capture_output=True, text=True, timeout=60)
        assert rep.returncode == 0, rep.stderr
        with Reader(bag) as reader:
            assert sum(1 for _ in reader.messages()) == n
    for mcap in bag.glob('*.mcap'):
        from mcap.reader import make_reader
        with open(mcap, 'rb') as f:
            n -= sum(1 for _ in make_reader(f).iter_messages())
    assert not list(bag.glob('*.mcap')) or n == 0
    return direct


@pytest.mark.slow
def test_kill_9_at_random_moments_loses_at_most_the_last_second(tmp_path, ros):
    """20 seeded trials (MCAP and sqlite3 alternately, five recorders at a time): each recorder is killed
    once the bag on disk holds N messages and K more were published (N, K seeded); every bag replays,
    without gaps, and lacks at most the last second of messages."""
    rng = np.random.default_rng(21)
    topic = '/bag_kill_test'
    source = Counter(ros, topic)
    trials = [{'storage': ('mcap', 'sqlite3')[i % 2], 'n': int(rng.integers(5, 60)), 'k': int(rng.integers(0, 60)),
               'bag': tmp_path / f'kill{i}'} for i in range(20)]
    # The recorders take their data over UDP: Fast DDS's shared-memory transport can leave a later
    # process deaf after a participant was killed with SIGKILL (eProsima/Fast-DDS#5469), and this test
    # kills 20.
    udp_only = {**os.environ, 'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'}

    def start(t):
        t['proc'] = tool('bag_record', '-o', str(t['bag']), '--storage', t['storage'], topic, env=udp_only)
        t['started'] = time.monotonic()
    t0 = time.monotonic()
    try:
        for batch in (trials[i:i + 5] for i in range(0, 20, 5)):
            for t in batch:
                start(t)

            def advance(batch=batch):
                for t in batch:
                    if 'target' not in t and on_disk(t['bag']) >= t['n']:
                        t['target'] = source.count + t['k']
                    elif 'target' not in t and not t.get('replaced') and time.monotonic() - t['started'] > 15.0 \
                            and on_disk(t['bag']) == 0:
                        # A recorder with nothing on disk after 15 s (3 of about 55 runs on 2026-11-26, also over
                        # UDP; cause not found) is replaced once, and counted below.
                        os.killpg(t['proc'].pid, signal.SIGKILL)
                        t['replaced'], t['stderr'] = True, t['proc'].communicate(timeout=10)[1][-2000:]
                        t['bag'] = t['bag'].with_name(t['bag'].name + '_again')
                        start(t)
                    if 'target' in t and 'killed' not in t and source.count >= t['target']:
                        t['killed'], t['published'] = time.time(), source.count
                        os.killpg(t['proc'].pid, signal.SIGKILL)
                return all('killed' in t for t in batch)
            ros.wait(advance, 50.0, 'every recorder of the batch to be killed')
            for t in batch:
                t['proc'].communicate(timeout=10)
                assert t['proc'].returncode == -signal.SIGKILL
    finally:
        source.close()
        for t in trials:        # a failed wait leaves recorders running: end them with the test
            if 'proc' in t and t['proc'].poll() is None:
                os.killpg(t['proc'].pid, signal.SIGKILL)
                t['proc'].communicate(timeout=10)
    elapsed = time.monotonic() - t0
    report = []
    for i, t in enumerate(trials):
        got, said = numbers(t['bag'])
        assert 'not closed by its recorder' in said[0]
        assert got and got == list(range(got[0], got[-1] + 1)), f'trial {i}: gaps or disorder'
        assert len(got) >= t['n']
        # At most the last second of messages lost: at most the last 100 the 100 Hz publisher sent. Counted
        # in messages, not wall time: a shared machine that stalls every process for seconds (seen at load
        # 11 on 2 cores) delays publisher and recorder alike.
        lost = t['published'] - 1 - got[-1]
        direct = readers_agree(t['bag'], len(got))
        report.append((t['storage'], len(got), lost, round(t['killed'] - source.times[got[-1]], 3),
                       direct == len(got), lost <= 100))
    print(f'\n20 kill trials in {elapsed:.1f} s; (storage, kept, lost, last kept before the kill [s], rosbags read '
          f'it as it was, at most 1 s of messages lost):')
    for r in report:
        print('  ', r)
    assert all(r[-1] for r in report), report
    assert all(r[4] for r in report), 'a killed bag needed bag_record --repair for rosbags'
    replaced = [(i, t['stderr']) for i, t in enumerate(trials) if t.get('replaced')]
    print(f'recorders replaced after recording nothing for 15 s: {len(replaced)}', replaced)
    assert len(replaced) <= 1, replaced

    # bag_replay plays a killed bag of each storage, all of it.
    from sensor_msgs.msg import Image
    for t in trials[:2]:
        got = []
        sub = ros.node.create_subscription(Image, topic, got.append,
                                           QoSProfile(history=HistoryPolicy.KEEP_ALL,
                                                      reliability=ReliabilityPolicy.RELIABLE), raw=True)
        rep = tool('bag_replay', str(t['bag']), '--fast', '--wait-for', topic)
        _, err = rep.communicate(timeout=60)
        assert rep.returncode == 0, err
        n = len(numbers(t['bag'])[0])
        ros.wait(lambda got=got, n=n: len(got) >= n, 20.0, 'the replayed messages')
        ros.node.destroy_subscription(sub)
        assert len(got) == n and 'not closed by its recorder' in err and f'replayed {n} messages' in err


@contextlib.contextmanager
def small_disk(path, size):
    """A directory on a file system of ``size`` bytes (a tmpfs mounted for the test, which needs root);
    where mounting is not allowed, a file size limit (RLIMIT_FSIZE) for the child instead, which makes
    writes fail with EFBIG as a full disk fails them with ENOSPC. Yields ``(directory, preexec_fn)``."""
    path.mkdir()
    mounted = subprocess.run(['mount', '-t', 'tmpfs', '-o', f'size={size}', 'tmpfs', str(path)],
                             capture_output=True).returncode == 0 if os.geteuid() == 0 else False
    try:
        yield path, (None if mounted else (lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))))
    finally:
        if mounted:
            subprocess.run(['umount', '-l', str(path)], check=True)


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_full_disk_ends_the_recording_cleanly_with_a_readable_bag(tmp_path, ros, storage):
    topic = '/bag_full_test'
    with small_disk(tmp_path / 'small', 5 << 20) as (disk, limit):
        # 2 MB/s: full after about 2 s. A history of 5 s: a reliable writer overwrites what its reader has
        # not taken yet, and with 0.5 s one run lost 244-247, just after the bag's first three messages.
        source = Counter(ros, topic, period=0.005, size=10000, depth=1000)
        try:
            rec = tool('bag_record', '-o', str(disk / 'bag'), '--storage', storage, topic, preexec_fn=limit)
            _, err = rec.communicate(timeout=60)
        finally:
            source.close()
        assert rec.returncode == 0, err
        assert 'Traceback' not in err and 'recording stopped early' in err, err
        assert 'disk full' in err or (limit is not None and 'file size limit' in err), err
        bag = disk / 'bag'
        info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
        assert info['custom_data']['recorder_state'].startswith('stopped:')
        got, said = numbers(bag)
        assert 'ended early' in said[0]
        assert len(got) > 20 and got == list(range(got[0], got[-1] + 1))
        assert info['message_count'] == len(got)
        readers_agree(bag, len(got))


def test_split_by_duration_and_size_from_the_command_line(tmp_path, ros):
    from rosbags.rosbag2 import Reader

    from sonar_tracking.cli.bag_record import parse_size
    assert (parse_size('100k'), parse_size('2M'), parse_size('1.5GiB'), parse_size('1000')) == (
        100 << 10, 2 << 20, 3 << 29, 1000)
    topic = '/bag_split_test'
    source = Counter(ros, topic, period=0.01, size=4000)
    try:
        for name, opts in (('dur', ['--split-duration', '0.3']), ('size', ['--split-size', '100k'])):
            bag = tmp_path / name
            rec = tool('bag_record', '-o', str(bag), *opts, topic)
            ros.wait(lambda bag=bag: on_disk(bag) >= 150, 30.0, '150 messages on disk')
            stop(rec)
            info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
            assert len(info['relative_file_paths']) >= 4, info['relative_file_paths']
            got, _ = numbers(bag, expect_warning=False)
            assert got == list(range(got[0], got[-1] + 1)) and len(got) == info['message_count']
            with Reader(bag) as reader:
                assert reader.message_count == len(got)
            if name == 'size':
                assert all(p.stat().st_size < 100_000 + 20_000 for p in bag.glob('*.mcap'))
    finally:
        source.close()
