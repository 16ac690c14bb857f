"""BagWriter without ROS: what a killed process, a torn file or a full disk leaves, split bags, repair."""
from __future__ import annotations

import re
import shutil
import signal
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest
import yaml

from sonar_tracking.io.bags import OPEN_TAIL, BagWriter, TruncatedBagWarning, bag_state, bag_topics, read_bag, repair

TOPIC, TYPE = '/numbers', 'std_msgs/msg/String'


@pytest.fixture(scope='module')
def typestore():
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def payload(i: int, size: int = 3000) -> bytes:
    return i.to_bytes(4, 'little') + bytes(size)


def numbers(bag, **kw) -> tuple[list[int], list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        got = [int.from_bytes(m.data[:4], 'little') for m in read_bag(bag, **kw)]
    return got, [str(w.message) for w in caught if issubclass(w.category, TruncatedBagWarning)]


def rosbags_numbers(path) -> list[int]:
    from rosbags.rosbag2 import Reader
    with Reader(path) as reader:
        return [int.from_bytes(bytes(d[:4]), 'little') for _, _, d in reader.messages()]


def mcap_numbers(bag) -> list[int]:
    from mcap.reader import make_reader
    out = []
    for file in sorted(bag.glob('*.mcap')):
        with open(file, 'rb') as f:
            out += [int.from_bytes(m.data[:4], 'little') for _, _, m in make_reader(f).iter_messages()]
    return out


def metadata(bag) -> dict:
    return yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']


def write_bag(path, typestore, storage='mcap', n=200, flush_every=25, close=True, **kw) -> BagWriter:
    w = BagWriter(path, storage, sync=False, **kw)
    w.open()
    conn = w.add_connection(TOPIC, TYPE, typestore=typestore)
    for i in range(n):
        w.write(conn, 10**9 + i * 10**7, payload(i))
        if flush_every and i % flush_every == flush_every - 1:
            w.flush()
    if close:
        w.close()
    return w


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_closed_bag_is_jazzy_version_9_and_every_reader_reads_it(tmp_path, typestore, storage):
    write_bag(tmp_path / 'b', typestore, storage)
    info = metadata(tmp_path / 'b')
    assert (info['version'], info['ros_distro'], info['custom_data']) == (9, 'jazzy', {'recorder_state': 'closed'})
    assert info['message_count'] == 200 and info['duration']['nanoseconds'] == 199 * 10**7
    assert info['topics_with_message_count'][0]['message_count'] == 200
    assert numbers(tmp_path / 'b') == (list(range(200)), [])
    assert rosbags_numbers(tmp_path / 'b') == list(range(200))
    if storage == 'mcap':
        assert mcap_numbers(tmp_path / 'b') == list(range(200))
    assert repair(tmp_path / 'b') == []          # nothing to do on a closed bag
    assert not list((tmp_path / 'b').glob('.*'))   # the space reserve is gone


KILL_SCRIPT = '''
import os, signal, sys
from rosbags.typesys import Stores, get_typestore
from sonar_tracking.io.bags import BagWriter
w = BagWriter(sys.argv[1], sys.argv[2])
w.open()
conn = w.add_connection('/numbers', 'std_msgs/msg/String', typestore=get_typestore(Stores.ROS2_JAZZY))
for i in range(int(sys.argv[3])):
    w.write(conn, 10**9 + i * 10**7, i.to_bytes(4, 'little') + bytes(3000))
    if i % 25 == 24:
        w.flush()
os.kill(os.getpid(), signal.SIGKILL)
'''


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_killed_writer_leaves_every_flushed_message(tmp_path, storage):
    bag = tmp_path / 'killed'
    proc = subprocess.run([sys.executable, '-c', KILL_SCRIPT, str(bag), storage, '140'], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    flushed = list(range(125))     # flushed after 25, 50, ..., 125 messages; 15 were not
    assert metadata(bag)['custom_data'] == {'recorder_state': 'recording'}
    assert metadata(bag)['message_count'] == 125
    got, said = numbers(bag)
    assert got == flushed and 'not closed by its recorder' in said[0] and '125 messages' in said[0]
    (topic,) = bag_topics(bag)
    assert topic.name == TOPIC and topic.msgtype == TYPE and 'string data' in topic.msgdef
    if storage == 'mcap':
        assert rosbags_numbers(bag) == flushed and mcap_numbers(bag) == flushed   # as it is, no repair
        (file,) = bag.glob('*.mcap')          # the file alone: no metadata, but it says it was not closed
        got, said = numbers(file)
        assert got == flushed and 'ends without a summary' in said[0]
    assert repair(bag)
    assert metadata(bag)['custom_data']['recorder_state'].startswith('repaired')
    assert rosbags_numbers(bag) == flushed and numbers(bag)[0] == flushed


def test_torn_files_read_to_the_last_complete_record_and_repair(tmp_path, typestore):
    """A file cut anywhere (power loss, a half write) or ending in zeros (its size reached the disk but
    its last page did not): read_bag reads a prefix and says where the cut is; after repair every
    reader reads the complete chunks."""
    write_bag(tmp_path / 'whole', typestore, n=300, close=False).abort()
    (mcap,) = (tmp_path / 'whole').glob('*.mcap')
    size = mcap.stat().st_size
    rng = np.random.default_rng(7)
    cuts = sorted(int(c) for c in rng.integers(100, size - len(OPEN_TAIL), 12))
    for k, cut in enumerate(cuts + ['zeros']):
        bag = tmp_path / f'torn{k}'
        shutil.copytree(tmp_path / 'whole', bag)
        (file,) = bag.glob('*.mcap')
        if cut == 'zeros':
            with open(file, 'r+b') as f:
                f.seek(size - 4096)
                f.write(bytes(4096))
        else:
            with open(file, 'r+b') as f:
                f.truncate(cut)
        got, said = numbers(bag)
        assert got == list(range(len(got))), k
        assert any('cut off at byte' in s for s in said), said
        repair(bag)
        after = rosbags_numbers(bag)
        assert after == got[:len(after)] and len(got) - len(after) <= 25 + 1, (k, len(got), len(after))
        assert mcap_numbers(bag) == after and numbers(bag)[0] == after


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_split_by_size_and_by_duration(tmp_path, typestore, storage):
    write_bag(tmp_path / 'size', typestore, storage, n=300, split_size=200_000)
    write_bag(tmp_path / 'time', typestore, storage, n=300, split_duration=0.5)   # 50 messages per file
    for name in ('size', 'time'):
        bag = tmp_path / name
        info = metadata(bag)
        files = info['relative_file_paths']
        assert len(files) >= 3 and files == [f'{name}_{i}.{"mcap" if storage == "mcap" else "db3"}'
                                             for i in range(len(files))]
        assert sum(f['message_count'] for f in info['files']) == 300 == info['message_count']
        assert numbers(bag) == (list(range(300)), []) and rosbags_numbers(bag) == list(range(300))
    assert [f['message_count'] for f in metadata(tmp_path / 'time')['files']] == [50] * 6
    for f in (tmp_path / 'size').iterdir():
        if f.suffix in ('.mcap', '.db3'):
            assert f.stat().st_size < 200_000 + 2 * 3100 + 20_000      # one message and a summary over


def test_split_bag_killed_reads_every_file(tmp_path, typestore):
    w = write_bag(tmp_path / 'b', typestore, n=260, split_duration=1.0, close=False)
    w.abort()
    got, said = numbers(tmp_path / 'b')
    assert got == list(range(250)) and said        # 10 not flushed; files 0 and 1 closed, 2 open
    assert len(bag_state(tmp_path / 'b').files) == 3


FULL_SCRIPT = '''
import resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (400_000, 400_000))
from rosbags.typesys import Stores, get_typestore
from sonar_tracking.io.bags import BagWriter, BagWriteError
w = BagWriter(sys.argv[1], sys.argv[2])
w.open()
conn = w.add_connection('/numbers', 'std_msgs/msg/String', typestore=get_typestore(Stores.ROS2_JAZZY))
try:
    for i in range(100000):
        w.write(conn, 10**9 + i * 10**7, i.to_bytes(4, 'little') + bytes(3000))
        if i % 25 == 24:
            w.flush()
except BagWriteError as exc:
    print(exc)
try:
    w.close()
except BagWriteError as exc:
    print('close:', exc)
'''


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_file_size_limit_ends_the_bag_like_a_full_disk(tmp_path, storage):
    """RLIMIT_FSIZE makes writes fail with EFBIG as a full disk fails them with ENOSPC (sqlite calls
    that a disk I/O error). sqlite keeps the last commits in its log, which the limit keeps from the
    database file: read_bag reads them, rosbags after a repair."""
    bag = tmp_path / 'limited'
    proc = subprocess.run([sys.executable, '-c', textwrap.dedent(FULL_SCRIPT), str(bag), storage],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert re.search('file size limit|disk full|disk I/O error', proc.stdout), proc.stdout
    info = metadata(bag)
    assert info['custom_data']['recorder_state'].startswith('stopped:')
    got, said = numbers(bag)
    assert len(got) > 50 and got == list(range(len(got))) and info['message_count'] == len(got)
    assert 'ended early' in said[0]
    if storage == 'mcap':
        assert rosbags_numbers(bag) == got and mcap_numbers(bag) == got
    else:
        repair(bag)
        assert rosbags_numbers(bag) == got


def test_topics_filter_and_a_folder_without_metadata(tmp_path, typestore):
    w = write_bag(tmp_path / 'b', typestore, n=60, close=False)
    w.abort()
    (tmp_path / 'b' / 'metadata.yaml').unlink()
    got, said = numbers(tmp_path / 'b')
    assert got == list(range(50)) and 'no readable metadata.yaml' in said[0]
    assert numbers(tmp_path / 'b', topics=['/other'])[0] == []
    with pytest.raises(Exception, match='holds no MCAP or sqlite3 file'):
        list(read_bag(tmp_path))   # a folder that is not a bag


def test_bytes_damaged_anywhere_after_the_header_cost_a_tail_never_a_crash(tmp_path, typestore):
    """Seeded random byte changes (as bad sectors or a torn page would make them): read_bag gives the
    messages before the first damaged record, in order; after repair rosbags reads the same."""
    write_bag(tmp_path / 'whole', typestore, n=300, close=False).abort()
    (mcap,) = (tmp_path / 'whole').glob('*.mcap')
    original = mcap.read_bytes()
    rng = np.random.default_rng(11)
    for k in range(40):
        data = bytearray(original)
        for p in rng.integers(64, len(data), int(rng.integers(1, 6))):     # past magic and header
            data[p] = (data[p] + int(rng.integers(1, 256))) % 256
        bag = tmp_path / f'damaged{k}'
        shutil.copytree(tmp_path / 'whole', bag)
        next(bag.glob('*.mcap')).write_bytes(bytes(data))
        got, _ = numbers(bag)
        assert got == list(range(len(got))), k
        repair(bag)
        after = rosbags_numbers(bag)
        assert after == got, k
