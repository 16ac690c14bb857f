"""Recordings killed with SIGKILL at every stage open without repair in rosbags, the mcap library,
bag_replay and sonar_import, and hold every message of the last flush that completed."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import time
import warnings

import pytest
import yaml

from sonar_tracking import process
from sonar_tracking.cli.sonar_import import main as sonar_import
from sonar_tracking.io.bags import TruncatedBagWarning, bag_topics, read_bag

IMAGE, FRAME = '/killed/image', '/killed/frame'

# A writer of the package's BagWriter that kills itself (SIGKILL) at a chosen stage: during open()
# just before its folder gets the bag's name, after messages but before any flush, or after flushes
# with unflushed messages behind them. Each message pair is a sensor_msgs/Image numbered in its
# frame_id (what bag_replay plays) and a ProjectedSonarImage (what sonar_import imports).
KILLER = textwrap.dedent('''
    import os, signal, sys
    import numpy as np
    from rosbags.typesys import Stores, get_typestore
    from sonar_tracking.io.bags import BagWriter
    from sonar_tracking.io.importers.msgdefs import BUILTIN_DEFINITIONS, register_definitions
    path, storage, stage, n, every = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5])
    if stage == 'open':
        os.rename = lambda *a: os.kill(os.getpid(), signal.SIGKILL)
    ts = get_typestore(Stores.ROS2_JAZZY)
    register_definitions(ts, BUILTIN_DEFINITIONS)
    t = ts.types
    w = BagWriter(path, storage)
    w.open()
    img = w.add_connection('{image}', 'sensor_msgs/msg/Image', typestore=ts)
    frame = w.add_connection('{frame}', 'marine_acoustic_msgs/msg/ProjectedSonarImage', typestore=ts)
    az = np.radians(np.linspace(-30.0, 30.0, 16))
    for k in range(n):
        ns = 1_700_000_000 * 10**9 + k * 10**8
        header = t['std_msgs/msg/Header'](stamp=t['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9),
                                          frame_id=str(k))
        image = t['sensor_msgs/msg/Image'](header=header, height=1, width=8, encoding='mono8', is_bigendian=0, step=8,
                                           data=np.zeros(8, np.uint8))
        sonar = t['marine_acoustic_msgs/msg/ProjectedSonarImage'](
            header=header,
            ping_info=t['marine_acoustic_msgs/msg/PingInfo'](frequency=1.2e6, sound_speed=1500.0,
                                                             tx_beamwidths=np.zeros(0, np.float32),
                                                             rx_beamwidths=np.zeros(0, np.float32)),
            beam_directions=[t['geometry_msgs/msg/Vector3'](x=0.0, y=-float(np.sin(a)), z=float(np.cos(a)))
                             for a in az],
            ranges=np.linspace(1.0, 10.0, 40).astype(np.float32),
            image=t['marine_acoustic_msgs/msg/SonarImageData'](is_bigendian=False, dtype=0, beam_count=16,
                                                              data=np.full(640, k % 250, np.uint8)))
        w.write(img, ns, ts.serialize_cdr(image, 'sensor_msgs/msg/Image'))
        w.write(frame, ns, ts.serialize_cdr(sonar, 'marine_acoustic_msgs/msg/ProjectedSonarImage'))
        if every and k % every == every - 1:
            w.flush()
    os.kill(os.getpid(), signal.SIGKILL)
''').format(image=IMAGE, frame=FRAME)


def numbers_of(images) -> list[int]:
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Image
    return [int(deserialize_message(bytes(d), Image).header.frame_id) for d in images]


def rosbags_images(bag) -> list[int]:
    from rosbags.rosbag2 import Reader
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic == IMAGE]
        return numbers_of(d for _, _, d in reader.messages(connections=conns))


def mcap_images(bag, topic=IMAGE) -> list[int]:
    from mcap.reader import make_reader
    out = []
    for file in sorted(bag.glob('*.mcap')):
        with open(file, 'rb') as f:
            out += numbers_of(m.data for _, _, m in make_reader(f).iter_messages(topics=[topic]))
    return out


def read_bag_images(bag) -> list[int]:
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', TruncatedBagWarning)
        return numbers_of(m.data for m in read_bag(bag, [IMAGE]))


def bag_replay(bag) -> tuple[int, str]:
    """Replay with no subscriber (``--fast`` does not wait for one): exit code and log."""
    proc = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.bag_replay', str(bag), '--fast',
                           '--topics', IMAGE], capture_output=True, text=True, timeout=120)
    return proc.returncode, proc.stderr


def kill_writer(bag, storage, stage, n, every):
    proc = subprocess.run([sys.executable, '-c', KILLER, str(bag), storage, stage, str(n), str(every)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == -signal.SIGKILL, proc.stderr


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
@pytest.mark.parametrize('stage,n,every,flushed', [
    ('first-flush', 7, 0, 0),          # messages written, none flushed
    ('later', 23, 5, 20),              # four flushes, three messages behind the last
])
def test_a_killed_writer_opens_everywhere_without_repair(tmp_path, capsys, storage, stage, n, every, flushed):
    bag = tmp_path / 'bag'
    kill_writer(bag, storage, stage, n, every)
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['custom_data'] == {'recorder_state': 'recording'} and info['message_count'] == 2 * flushed
    expected = list(range(flushed))
    assert rosbags_images(bag) == expected            # sqlite3: rosbags reads the file immutable, no log
    if storage == 'mcap':
        assert mcap_images(bag) == expected
    assert read_bag_images(bag) == expected
    code, err = bag_replay(bag)
    assert code == 0 and 'Traceback' not in err and f'replayed {flushed} messages' in err, err
    code = sonar_import([str(bag), '-o', str(tmp_path / 'out')])
    err = capsys.readouterr().err
    assert 'Traceback' not in err
    if flushed:
        assert code == 1 and 'not closed by its recorder' in err, err      # imported, the cut reported
        assert sum(m.topic == '/sonar/sector' for m in read_bag(tmp_path / 'out')) == flushed
    else:
        assert code == 2 and 'no sonar topic recognised' in err and not (tmp_path / 'out').exists(), err
    assert {t.name for t in bag_topics(bag)} == ({IMAGE, FRAME} if flushed else set())


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_writer_killed_before_its_folder_has_the_bag_name_leaves_no_bag(tmp_path, capsys, storage):
    """The folder is built under a hidden name and renamed when it is a bag: killed before, there is no bag
    (a clear error for bag_replay and sonar_import), only the hidden folder."""
    bag = tmp_path / 'bag'
    kill_writer(bag, storage, 'open', 5, 0)
    assert not bag.exists()
    assert [p.name for p in tmp_path.iterdir()] == [f'.bag.creating-{p.name.rsplit("-", 1)[1]}'
                                                    for p in tmp_path.iterdir()]
    code, err = bag_replay(bag)
    assert code == 1 and 'does not exist' in err and 'Traceback' not in err, err
    assert sonar_import([str(bag), '-o', str(tmp_path / 'out')]) == 2
    assert 'does not exist' in capsys.readouterr().err


# ---------------------------------------------------------------------- bag_record killed while recording
class Numbered:
    """Images numbered in their frame_id, published on a timer of the test's node (100 Hz)."""

    def __init__(self, ros, topic, period=0.01):
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import Image
        self.msg = Image(height=1, width=1000, encoding='mono8', step=1000, data=bytes(1000))
        reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.pub = ros.node.create_publisher(Image, topic, reliable)
        self.times: list[float] = []
        self.ros = ros
        self.timer = ros.node.create_timer(period, self.publish)

    def publish(self):
        self.msg.header.frame_id = str(len(self.times))
        self.times.append(time.time())
        self.pub.publish(self.msg)

    def close(self):
        self.ros.node.destroy_timer(self.timer)
        self.ros.node.destroy_publisher(self.pub)


def flushed_count(bag) -> int:
    """The count of the last completed flush: bag_record rewrites metadata.yaml (atomically) after the
    data of each flush is on disk, so a count read here is on disk. Read with a pattern, not a YAML parser,
    to keep the polling light."""
    try:
        m = re.search(r'^  message_count: (\d+)$', (bag / 'metadata.yaml').read_text(), re.M)
    except OSError:
        return 0
    return int(m.group(1)) if m else 0


def recorder(bag, storage, topic, *extra):
    env = {**os.environ, 'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'}   # see test_bags: SHM after SIGKILL
    return subprocess.Popen([sys.executable, '-m', 'sonar_tracking.cli.bag_record', '-o', str(bag), '--storage',
                             storage, *extra, topic], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env=env, preexec_fn=process.child_dies_with_parent())


def kill(rec) -> None:
    """SIGKILL the recorder's process group (if it still runs) and collect it."""
    if rec.poll() is None:
        os.killpg(rec.pid, signal.SIGKILL)
    rec.communicate(timeout=10)


def wait_line(proc, pattern, ros, timeout=30.0):
    """Wait until the process logs a line matching ``pattern`` (stderr, read without blocking)."""
    os.set_blocking(proc.stderr.fileno(), False)
    seen = []

    def found():
        while (line := proc.stderr.readline()):
            seen.append(line)
            if re.search(pattern, line):
                return True
        return proc.poll() is not None and bool(seen.append(f'exited with {proc.returncode}'))
    ros.wait(found, timeout, f'{pattern!r} from the recorder')
    os.set_blocking(proc.stderr.fileno(), True)
    assert proc.poll() is None, ''.join(seen)


@pytest.mark.ros
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_bag_record_killed_after_a_flush_it_completed_keeps_everything_before(tmp_path, ros, capsys, storage):
    """SIGKILL right after the test saw a flush complete (its count in metadata.yaml, a condition): every
    message up to that flush is in the bag for every reader, without repair; what is lost was published
    after the last completed flush."""
    topic = f'/killed_record_{storage}'
    bag = tmp_path / 'bag'
    source = Numbered(ros, topic)
    rec = recorder(bag, storage, topic)
    try:
        wait_line(rec, f'recording {topic}', ros)
        ros.wait(lambda: flushed_count(bag) >= 40, 30.0, '40 messages flushed')
        before = flushed_count(bag)
        ros.wait(lambda: flushed_count(bag) > before, 10.0, 'the next flush')   # one more, seen complete
        seen = flushed_count(bag)
        os.killpg(rec.pid, signal.SIGKILL)
        killed_at, published = time.time(), len(source.times)
        rec.communicate(timeout=10)
    finally:
        source.close()
        kill(rec)
    from rosbags.rosbag2 import Reader
    with Reader(bag) as reader:
        got = numbers_of(d for _, _, d in reader.messages())
    first = got[0]
    assert got == list(range(first, first + len(got))), 'gaps or disorder'
    assert len(got) >= seen, (len(got), seen)                # every message of the flush seen complete
    assert flushed_count(bag) == len(got)                   # and exactly what the last completed flush wrote
    if storage == 'mcap':
        assert mcap_images(bag, topic) == got
    with pytest.warns(TruncatedBagWarning, match='not closed by its recorder'):
        assert numbers_of(m.data for m in read_bag(bag)) == got
    lost = published - (first + len(got))
    with capsys.disabled():
        print(f'\n{storage}: kept {len(got)} (flush seen: {seen}), lost {lost} messages, the last kept published '
              f'{killed_at - source.times[got[-1]]:.3f} s before the kill')
    proc = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.bag_replay', str(bag), '--fast'],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and f'replayed {len(got)} messages' in proc.stderr, proc.stderr
    code = sonar_import([str(bag), '--inspect'])
    out = capsys.readouterr().out
    assert code == 2 and re.search(rf'{topic}\s+sensor_msgs/msg/Image\s+{len(got)} msgs', out), out


@pytest.mark.ros
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_bag_record_killed_before_its_first_flush_opens_everywhere(tmp_path, ros, storage):
    topic = f'/killed_early_{storage}'
    bag = tmp_path / 'bag'
    source = Numbered(ros, topic)
    rec = recorder(bag, storage, topic, '--flush-interval', '3600')
    try:
        wait_line(rec, f'recording {topic}', ros)
        kill(rec)
    finally:
        source.close()
        kill(rec)
    from rosbags.rosbag2 import Reader
    with Reader(bag) as reader:
        assert list(reader.messages()) == []
    if storage == 'mcap':
        assert mcap_images(bag, topic) == []
    with pytest.warns(TruncatedBagWarning, match='not closed by its recorder'):
        assert list(read_bag(bag)) == []
    proc = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.bag_replay', str(bag), '--fast'],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and 'replayed 0 messages' in proc.stderr and 'Traceback' not in proc.stderr
