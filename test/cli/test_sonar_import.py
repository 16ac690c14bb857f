"""sonar_import: recordings written here in each sensor's format come out as the sector contract.

Each test writes a small recording of a static scene: the sonar at a known pose (odometry where the
format has it) and one bright point target at a known range and bearing. The imported bag is read
back through sonar_tracking.msgs and run through the FLS front end (core FlsProcessor); the brightest
region must be at the target's world position within one resolution cell, so a mirrored bearing
(wrong handedness) fails. Every ping must come out as exactly one sector column with its own
stamp and bearing (nothing lost, nothing duplicated).
"""
from __future__ import annotations

import math
import re
import struct
from pathlib import Path

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.cli.sonar_import import main as sonar_import
from sonar_tracking.core.fls import FlsProcessor
from sonar_tracking.io.bags import read_bag

POSE = (3.0, -2.0, 0.5)                # sonar x, y [m], yaw [rad] in the world
N_BINS, BIN = 200, 0.05                # samples per ping and their spacing [m]
TARGET_BIN, TARGET_BEARING = 120, 0.6  # target: bin centre 6.025 m, 34 deg to port
TARGET_RANGE = (TARGET_BIN + 0.5) * BIN
STEP = math.radians(1.8)               # head step
PERIOD_NS = 20_000_000                 # ping every 20 ms
T0 = 1_700_000_000 * 10**9

# Driver-style definitions under package names of the test's own, so recognition by fields and
# registration from the bag's own definitions are what is exercised.
SCANLINE_DEFS = {
    'micron_test/msg/Bin': 'float32 distance\nuint8 intensity\n',
    'micron_test/msg/ScanLine': 'std_msgs/Header header\nfloat32 angle\nfloat32 bin_distance_step\n'
                                'micron_test/Bin[] bins\n',
}
ECHO_DEF = ('std_msgs/Header header\nfloat32 angle\nuint8 gain\nuint16 number_of_samples\nuint16 transmit_frequency\n'
            'uint16 speed_of_sound\nuint8 range\nuint8[] intensities\n')
# bluerobotics_sonar's Ping360: whole gradians, range from the sample period (25 ns ticks) alone.
PING360_DEF = ('std_msgs/Header header\nfloat32 distance\nuint8 mode\nuint8 gain_setting\nuint16 angle\n'
               'uint16 transmit_duration\nuint16 sample_period\nuint16 transmit_frequency\nfloat32 range\n'
               'uint8[] profile_data\n')
PING360_TICKS = 2667                    # 1500 m/s * 2667 * 25 ns / 2 = 0.0500 m per sample


def world_target():
    x, y, yaw = POSE
    b = yaw + TARGET_BEARING
    return x + TARGET_RANGE * math.cos(b), y + TARGET_RANGE * math.sin(b)


def head_bearings(mode: str) -> np.ndarray:
    """REP-103 bearings of successive pings: 1.4 turns, or sweeps of +-70 deg: up, down, up, half down."""
    if mode == 'continuous':
        n = int(1.4 * 2 * math.pi / STEP)
        return np.remainder(-math.pi + 0.3 + STEP * np.arange(n) + math.pi, 2 * math.pi) - math.pi
    k = int(round(math.radians(70) / STEP))
    up = np.arange(-k, k + 1)
    down = np.arange(k - 1, -k - 1, -1)
    return STEP * np.concatenate([up, down, up[1:], down[: len(down) // 2]])


def ping_samples(bearing: float, rng: np.random.Generator, n: int = N_BINS) -> np.ndarray:
    """8-bit log-compressed counts: speckle background, the target 3 bins x 3 beams wide."""
    s = rng.integers(30, 60, n).astype(np.uint8)
    d = abs(math.remainder(bearing - TARGET_BEARING, 2 * math.pi)) / STEP
    if d <= 1.5:
        s[TARGET_BIN - 1:TARGET_BIN + 2] = (200, 240, 200) if d <= 0.5 else (170, 200, 170)
    return s


def typestore(ros1: bool, defs: dict[str, str] | None = None):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_JAZZY)
    for name, text in (defs or {}).items():
        ts.register(get_types_from_msg(text, name))
    return ts


def new(ts, name, **fields):
    return ma.RosbagsTypes(ts).new(name, **fields)


def header(ts, ns, ros1):
    stamp = new(ts, 'builtin_interfaces/msg/Time', sec=ns // 10**9, nanosec=ns % 10**9)
    return new(ts, 'std_msgs/msg/Header', stamp=stamp, frame_id='sonar')


def odometry(ts, ns, ros1):
    x, y, yaw = POSE
    pose = new(ts, 'geometry_msgs/msg/Pose',
               position=new(ts, 'geometry_msgs/msg/Point', x=x, y=y, z=-5.0),
               orientation=new(ts, 'geometry_msgs/msg/Quaternion', x=0.0, y=0.0, z=math.sin(yaw / 2),
                               w=math.cos(yaw / 2)))
    return new(ts, 'nav_msgs/msg/Odometry', header=header(ts, ns, ros1), child_frame_id='base_link',
               pose=new(ts, 'geometry_msgs/msg/PoseWithCovariance', pose=pose))


class BagOut:
    """A ROS 1 or ROS 2 bag written with rosbags; ``write(topic, type, msg, ns)``."""

    def __init__(self, path: Path, ros1: bool, ts, storage: str = 'mcap', chunk_bytes: int = 0) -> None:
        from rosbags.rosbag1 import Writer as W1
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as W2
        self.ros1, self.ts, self.conns = ros1, ts, {}
        plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
        self.w = W1(path) if ros1 else W2(path, version=8, storage_plugin=plugin)
        if chunk_bytes:
            self.w.chunk_threshold = chunk_bytes
        self.w.open()

    def write(self, topic, msgtype, msg, ns) -> None:
        if topic not in self.conns:
            self.conns[topic] = self.w.add_connection(topic, msgtype, typestore=self.ts)
        data = self.ts.serialize_ros1(msg, msgtype) if self.ros1 else self.ts.serialize_cdr(msg, msgtype)
        self.write_raw(topic, data, ns)

    def write_raw(self, topic, data, ns) -> None:
        self.w.write(self.conns[topic], ns, data)

    def close(self) -> None:
        self.w.close()


def write_scanning(path: Path, kind: str, mode: str, clockwise: bool, ros1: bool, seed: int = 1,
                   with_odometry: bool = True, storage: str = 'mcap', chunk_bytes: int = 0,
                   package: str = '') -> list[tuple[int, float]]:
    """A bag of per-ping messages; returns the (stamp_ns, REP-103 bearing) of every ping. ``package``
    replaces the package name of the message types (micron_test, ping_test)."""
    rng = np.random.default_rng(seed)
    if kind == 'scanline':
        pkg = package or 'micron_test'
        defs = {k.replace('micron_test', pkg): v.replace('micron_test', pkg) for k, v in SCANLINE_DEFS.items()}
        ts, msgtype, zero, unit = typestore(ros1, defs), f'{pkg}/msg/ScanLine', 180.0, 180 / math.pi
    elif kind == 'ping360':
        msgtype = f'{package or "ping_test"}/msg/SonarPing360'
        ts, zero, unit = typestore(ros1, {msgtype: PING360_DEF}), 0.0, 200 / math.pi
    else:  # echoes in radians (ROS 2 ping360_sonar) or gradians 0..399 (its ROS 1 driver)
        msgtype = f'{package or "ping_test"}/msg/SonarEcho'
        ts, zero = typestore(ros1, {msgtype: ECHO_DEF}), 0.0
        unit = 1.0 if kind == 'echo_rad' else 200 / math.pi
    out = BagOut(path, ros1, ts, storage, chunk_bytes)
    pings = []
    for k, b in enumerate(head_bearings(mode)):
        ns = T0 + k * PERIOD_NS
        head = (-b if clockwise else b) * unit + zero
        if kind == 'echo_grad':
            head = head % 400.0
        s = ping_samples(b, rng)
        if kind == 'ping360':   # the head's whole gradian is the recorded bearing
            head = int(round(head)) % 400
            b = math.remainder((-head if clockwise else head) / unit, 2 * math.pi)
            msg = new(ts, msgtype, header=header(ts, ns, ros1), distance=0.0, mode=1, gain_setting=0, angle=head,
                      transmit_duration=10, sample_period=PING360_TICKS, transmit_frequency=750, range=0.0,
                      profile_data=s)
        elif kind == 'scanline':
            bins = [new(ts, msgtype.replace('ScanLine', 'Bin'), distance=0.0, intensity=int(v)) for v in s]
            msg = new(ts, msgtype, header=header(ts, ns, ros1), angle=head, bin_distance_step=BIN, bins=bins)
        else:
            msg = new(ts, msgtype, header=header(ts, ns, ros1), angle=head, number_of_samples=N_BINS,
                      range=int(N_BINS * BIN), intensities=s, speed_of_sound=1500)
        out.write('/sonar/raw', msgtype, msg, ns + 1_000_000)
        pings.append((ns, float(b)))
        if with_odometry and k % 10 == 0:
            out.write('/nav/odom', 'nav_msgs/msg/Odometry', odometry(ts, ns, ros1), ns)
    out.close()
    return pings


def read_output(bag: Path):
    """Imported sectors (amplitudes, geometry, stamp_ns, encoding) in bag order, and odometry poses."""
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    pairer, sectors, poses = ma.SectorPairer(), [], []
    for m in read_bag(bag):
        msgtype = {'/sonar/sector': 'sensor_msgs/msg/Image', '/sonar/sector_info': 'sensor_msgs/msg/LaserScan',
                   '/platform/odometry': 'nav_msgs/msg/Odometry'}[m.topic]
        msg = ts.deserialize_cdr(m.data, msgtype)
        if m.topic == '/platform/odometry':
            poses.append((ma.header_ns(msg), ma.odometry_to_pose(msg)))
            continue
        pair = pairer.add_image(msg) if m.topic == '/sonar/sector' else pairer.add_info(msg)
        if pair is not None:
            a, g = ma.sector_from_messages(pair.image, pair.info)
            sectors.append((a, g, pair.stamp_ns, pair.image.encoding))
    assert not pairer.pop_dropped()
    return sectors, poses


def columns(sectors, t0: int = T0) -> list[tuple[float, float]]:
    """(time [s] since t0, bearing) of every sector column, from stamp + j * ping_period."""
    out = []
    for _, g, stamp, _ in sectors:
        for j, b in enumerate(g.bearings()):
            out.append(((stamp - t0) / 1e9 + j * g.ping_period, math.remainder(b, 2 * math.pi)))
    return sorted(out)


def assert_every_ping_once(sectors, pings, t0: int = T0) -> None:
    cols = columns(sectors, t0)
    assert len(cols) == len(pings)
    want = sorted(((ns - t0) / 1e9, b) for ns, b in pings)
    t = np.array(cols)
    w = np.array(want)
    assert np.max(np.abs(t[:, 0] - w[:, 0])) < 1e-4
    assert np.max(np.abs(np.remainder(t[:, 1] - w[:, 1] + math.pi, 2 * math.pi) - math.pi)) < 1e-4


def fls_target(sectors, poses, decode_db: float = 0.0):
    """World (x, y) of the brightest FLS region and the resolution cell it must lie within."""
    from sonar_tracking.core.intensity import decode, full_scale_of
    proc = FlsProcessor()
    frames = []
    for a, g, stamp, _ in sectors:
        if decode_db:
            a = decode(a, 'db', db_span=decode_db, full_scale=full_scale_of(a.dtype))
        pose = min(poses, key=lambda p: abs(p[0] - stamp))[1] if poses else (0.0, 0.0, 0.0)
        frames += proc.add_sector(a, g, pose, stamp / 1e9)
    last = proc.flush()
    frames += [last] if last is not None else []
    regions = np.concatenate([f.regions for f in frames])
    assert len(regions), 'the front end found no region'
    best = regions[np.argmax(regions['f03'])]
    return (best['x'], best['y'], best['bearing']), target_cell(sectors[0][1], proc.config.image.resolution)


def target_cell(g, resolution: float) -> float:
    """The diagonal of the resolution cell at the target: a sector's bin and beam, or an image pixel."""
    return math.hypot(max(g.range_resolution, resolution), max(TARGET_RANGE * g.angle_increment, resolution))


def check_target(sectors, poses, decode_db: float = 0.0) -> None:
    (x, y, bearing), cell = fls_target(sectors, poses, decode_db)
    tx, ty = world_target()
    assert math.hypot(x - tx, y - ty) <= cell, f'region at ({x:.2f}, {y:.2f}), target at ({tx:.2f}, {ty:.2f})'
    assert bearing > 0  # to port, as recorded


def run(*args) -> int:
    return sonar_import([str(a) for a in args])


# -- scanning sonars in ROS bags -------------------------------------------------------------------

@pytest.mark.parametrize('kind,mode,clockwise,ros1', [
    ('scanline', 'sector', True, True),       # Tritech driver on ROS 1: degrees, 180 = forward, clockwise
    ('scanline', 'continuous', False, 'sqlite3'),
    ('echo_rad', 'continuous', True, False),  # ping360_sonar on ROS 2: radians
    ('echo_grad', 'sector', False, True),     # ping360_sonar on ROS 1: gradians
    ('echo_grad', 'continuous', True, True),
    ('ping360', 'continuous', True, False),   # bluerobotics_sonar: uint16 gradians, sample period
    ('ping360', 'sector', False, True),
])
def test_scanning_sonar_bag(tmp_path, kind, mode, clockwise, ros1):
    src = tmp_path / ('in.bag' if ros1 is True else 'in')
    pings = write_scanning(src, kind, mode, clockwise, ros1 is True, storage=ros1 or 'mcap')
    args = [src, '-o', tmp_path / 'out', '--intensity', 'db', '--db-span', 60]
    args += ['--clockwise'] if clockwise else ['--counter-clockwise']
    if kind == 'scanline':
        args += ['--head-zero', 180]
    assert run(*args) == 0
    sectors, poses = read_output(tmp_path / 'out')
    assert len(poses) == math.ceil(len(pings) / 10)
    assert_every_ping_once(sectors, pings)
    assert all(enc == '32FC1' for *_, enc in sectors)
    if mode == 'sector':  # one sector per sweep, cut at each reversal; the last, partial sweep too
        assert [g.n_beams for _, g, _, _ in sectors] == [79, 78, 78, 39]
        assert [g.ping_period > 0 for _, g, _, _ in sectors] == [True, False, True, False]
    else:                 # 1.4 turns: one full turn and the partial last sweep
        assert len(sectors) == 2 and sectors[0][1].n_beams == 200
    check_target(sectors, poses)


@pytest.mark.ros
@pytest.mark.parametrize('clockwise', [True, False])
def test_imported_bag_through_the_fls_features_node(tmp_path, inproc, clockwise):
    """The imported bag given to the ``fls_features`` node message by message in bag order, as a
    replay would (through its own subscriptions: pairing, odometry buffer, time rule): the
    brightest region of ``/fls/regions`` is the target, in the world frame, within one cell, to port."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Image, LaserScan

    from sonar_tracking.nodes.fls_features import FlsFeaturesNode
    write_scanning(tmp_path / 'in', 'echo_rad', 'continuous', clockwise, ros1=False, seed=4)
    direction = '--clockwise' if clockwise else '--counter-clockwise'
    assert run(tmp_path / 'in', '-o', tmp_path / 'out', '--intensity', 'db', direction) == 0
    node = inproc(FlsFeaturesNode)
    published = []
    node.pub_regions.publish = published.append
    subs = {s.topic_name: s for s in node.subscriptions}
    types = {'/sonar/sector': Image, '/sonar/sector_info': LaserScan, '/platform/odometry': Odometry}
    for m in read_bag(tmp_path / 'out'):
        subs[m.topic].callback(deserialize_message(bytes(m.data), types[m.topic]))
    assert published, 'fls_features published no regions'
    assert {m.header.frame_id for m in published} == {'world'}
    regions = np.concatenate([ma.cloud_to_array(m) for m in published])
    best = regions[np.argmax(regions['f03'])]
    cell = target_cell(read_output(tmp_path / 'out')[0][0][1], node.config.image.resolution)
    tx, ty = world_target()
    assert math.hypot(best['x'] - tx, best['y'] - ty) <= cell and best['bearing'] > 0


def test_pose_stamped_as_platform_pose(tmp_path, capsys):
    """A PoseStamped topic named by --odometry-topic gives /platform/odometry; unnamed, it is only listed."""
    ts = typestore(True, {'ping_test/msg/SonarEcho': ECHO_DEF})
    out = BagOut(tmp_path / 'in.bag', True, ts)
    rng = np.random.default_rng(12)
    x, y, yaw = POSE
    pings = []
    for k, b in enumerate(head_bearings('continuous')):
        ns = T0 + k * PERIOD_NS
        msg = new(ts, 'ping_test/msg/SonarEcho', header=header(ts, ns, True), angle=float(b), number_of_samples=N_BINS,
                  range=int(N_BINS * BIN), intensities=ping_samples(b, rng))
        out.write('/echo', 'ping_test/msg/SonarEcho', msg, ns)
        pings.append((ns, float(b)))
        if k % 10 == 0:
            pose = odometry(ts, ns, True).pose.pose
            out.write('/nav/pose', 'geometry_msgs/msg/PoseStamped',
                      new(ts, 'geometry_msgs/msg/PoseStamped', header=header(ts, ns, True), pose=pose), ns)
    out.close()
    assert run(tmp_path / 'in.bag', '--inspect') == 0
    assert 'pose -> /platform/odometry if named' in capsys.readouterr().out
    assert run(tmp_path / 'in.bag', '-o', tmp_path / 'out', '--odometry-topic', '/nav/pose', '--intensity', 'db') == 0
    sectors, poses = read_output(tmp_path / 'out')
    assert len(poses) == math.ceil(len(pings) / 10)
    assert all(np.allclose(p, POSE) for _, p in poses)
    assert_every_ping_once(sectors, pings)
    check_target(sectors, poses)


def test_pings_per_sector_and_kept_counts(tmp_path):
    pings = write_scanning(tmp_path / 'in', 'echo_rad', 'sector', False, ros1=False, seed=2)
    assert run(tmp_path / 'in', '-o', tmp_path / 'out', '--pings', 16) == 0
    sectors, poses = read_output(tmp_path / 'out')
    assert_every_ping_once(sectors, pings)
    # Sectors never straddle a reversal: sweeps of 79, 78, 78 and 39 pings are cut into 16s and a rest.
    assert [g.n_beams for _, g, _, _ in sectors] == [16] * 4 + [15] + ([16] * 4 + [14]) * 2 + [16, 16, 7]
    # Kept values: mono8 counts as recorded, decoded here with the front end's coding.
    assert all(enc == 'mono8' for *_, enc in sectors)
    check_target(sectors, poses, decode_db=60.0)


def test_wrong_head_direction_mirrors_the_target(tmp_path):
    """The handedness check can fail: importing a clockwise head as counter-clockwise mirrors it."""
    write_scanning(tmp_path / 'in', 'echo_rad', 'continuous', True, ros1=False, seed=3)
    assert run(tmp_path / 'in', '-o', tmp_path / 'out', '--intensity', 'db', '--counter-clockwise') == 0
    (x, y, bearing), cell = fls_target(*read_output(tmp_path / 'out'))
    tx, ty = world_target()
    assert bearing < 0 and math.hypot(x - tx, y - ty) > 5 * cell


# -- conventions from the message type ----------------------------------------------------------------

@pytest.mark.parametrize('kind,package,ros1', [
    ('scanline', 'micron_driver_ros', True),     # the type names the sensor
    ('scanline', 'sonar_driver', False),         # the fields are a Tritech scan line's
    ('echo_grad', 'ping360_sonar', True),        # ROS 1 ping360_sonar: gradians
    ('ping360', 'bluerobotics_sonar_msgs', False),
])
def test_a_sensor_named_by_its_message_type_gets_its_conventions(tmp_path, capsys, kind, package, ros1):
    """Without --preset or options a Tritech bag turns clockwise with 180 deg ahead, a Ping360 bag
    clockwise with 0 grad ahead: the target comes out where it was, not mirrored."""
    src = tmp_path / ('in.bag' if ros1 else 'in')
    pings = write_scanning(src, kind, 'sector', True, ros1, seed=21, package=package)
    assert run(src, '-o', tmp_path / 'out') == 0
    assert 'note:' not in capsys.readouterr().err
    sectors, poses = read_output(tmp_path / 'out')
    assert_every_ping_once(sectors, pings)
    check_target(sectors, poses, decode_db=60.0)


def convention_rows(out: str) -> dict[str, str]:
    """The rows of --inspect's conventions table by their first two words."""
    lines = out.split('\nconventions ', 1)[1].splitlines()[1:]
    return {line.split()[0] + ' ' + line.split()[1]: line for line in lines if line.startswith('  ')}


def test_inspect_names_each_convention_and_its_source(tmp_path, capsys):
    write_scanning(tmp_path / 'in.bag', 'scanline', 'sector', True, ros1=True, package='micron_driver_ros')
    assert run(tmp_path / 'in.bag', '--inspect') == 0
    rows = convention_rows(capsys.readouterr().out)
    by_type = 'from message type micron_driver_ros/msg/ScanLine: Tritech Micron/SeaKing (preset micron_seaking)'
    assert rows['head direction'].split()[2] == 'clockwise' and by_type in rows['head direction']
    assert '180 deg' in rows['head zero'] and by_type in rows['head zero']
    assert rows['angle unit'].split()[2] == 'deg' and by_type in rows['angle unit']
    assert 'kept as recorded' in rows['intensity kept'] and by_type in rows['intensity kept']
    # An option beats the preset, the preset beats the message type.
    assert run(tmp_path / 'in.bag', '--inspect', '--preset', 'ping360', '--intensity', 'db', '--angle-unit',
               'deg') == 0
    rows = convention_rows(capsys.readouterr().out)
    assert rows['head direction'].endswith('from preset ping360')
    assert '0 deg' in rows['head zero'] and rows['head zero'].endswith('from preset ping360')
    assert rows['angle unit'].endswith('from option --angle-unit')
    assert 'decoded from db' in rows['intensity decoded'] and rows['intensity decoded'].endswith('option --intensity')


def test_a_type_naming_no_sensor_keeps_the_defaults_and_says_so(tmp_path, capsys):
    write_scanning(tmp_path / 'in', 'echo_rad', 'sector', False, ros1=False, package='acme_msgs')
    assert run(tmp_path / 'in', '--inspect') == 0
    captured = capsys.readouterr()
    rows = list(convention_rows(captured.out).values())
    assert [r.split()[-1] for r in rows] == ['default'] * 4
    assert 'counter-clockwise' in rows[0] and '0 deg' in rows[1] and 'rad (auto' in rows[2]
    assert 'note: message type acme_msgs/msg/SonarEcho names no sensor' in captured.err
    assert '--clockwise' in captured.err


# -- imaging sonars: ProjectedSonarImage ----------------------------------------------------------

PROJECTED_DEFS = {
    'marine_acoustic_msgs/msg/PingInfo': 'float32 frequency\nfloat32 sound_speed\nfloat32[] tx_beamwidths\n'
                                         'float32[] rx_beamwidths\n',
    'marine_acoustic_msgs/msg/SonarImageData': 'bool is_bigendian\nuint32 dtype\nuint32 beam_count\nuint8[] data\n',
    'marine_acoustic_msgs/msg/ProjectedSonarImage':
        'std_msgs/Header header\nmarine_acoustic_msgs/PingInfo ping_info\ngeometry_msgs/Vector3[] beam_directions\n'
        'float32[] ranges\nmarine_acoustic_msgs/SonarImageData image\n',
}


# SonarImageData dtype codes, and the full scale the test writes each type with (8-bit counts
# scaled to it; the wide integers carry the counts as they are).
DTYPE_CODES = {np.uint8: 0, np.int8: 1, np.uint16: 2, np.int16: 3, np.uint32: 4, np.int32: 5, np.uint64: 6,
               np.int64: 7, np.float32: 8, np.float64: 9}
FULL_SCALE = {np.uint8: 255.0, np.int8: 127.0, np.uint16: 65535.0, np.int16: 32767.0, np.float32: 1.0,
              np.float64: 1.0}


def write_projected(path: Path, ros1: bool, frame: str, dtype, layout: str, n_frames: int = 4,
                    big_endian: bool = False) -> int:
    """Frames of 96 unevenly spaced beams over +-65 deg; returns the number of frames."""
    rng = np.random.default_rng(5)
    ts = typestore(ros1, PROJECTED_DEFS)
    out = BagOut(path, ros1, ts)
    az = np.arcsin(np.linspace(-1, 1, 96) * math.sin(math.radians(65)))   # REP-103, denser at the centre
    if frame == 'message':   # z forward, x up, y starboard: y = -sin(bearing)
        dirs = [new(ts, 'geometry_msgs/msg/Vector3', x=0.0, y=-math.sin(a), z=math.cos(a)) for a in az]
    else:                    # DAVE: x forward, y port, z = 0
        dirs = [new(ts, 'geometry_msgs/msg/Vector3', x=math.cos(a), y=math.sin(a), z=0.0) for a in az]
    dirs = dirs[::-1]        # beams listed starboard to port... reversed: the importer sorts them
    azl = az[::-1]
    ranges = (np.arange(N_BINS) + 0.5) * BIN
    full = FULL_SCALE.get(dtype, 255.0)
    for k in range(n_frames):
        ns = T0 + k * 100_000_000
        counts = rng.integers(30, 60, (N_BINS, len(az))).astype(np.float64)
        beam = int(np.argmin(np.abs(azl - TARGET_BEARING)))
        counts[TARGET_BIN - 1:TARGET_BIN + 2, beam - 1:beam + 2] = 200
        counts[TARGET_BIN, beam] = 240
        values = (counts / 255.0 * full).astype(np.dtype(dtype).newbyteorder('>' if big_endian else '<'))
        data = values if layout == 'range_major' else values.T
        img = new(ts, 'marine_acoustic_msgs/msg/SonarImageData', is_bigendian=big_endian, dtype=DTYPE_CODES[dtype],
                  beam_count=len(az),
                  data=np.ascontiguousarray(data).reshape(-1).view(np.uint8))
        msg = new(ts, 'marine_acoustic_msgs/msg/ProjectedSonarImage', header=header(ts, ns, ros1), beam_directions=dirs,
                  ranges=ranges.astype(np.float32), image=img)
        out.write('/oculus/sonar_image', 'marine_acoustic_msgs/msg/ProjectedSonarImage', msg, ns)
        out.write('/nav/odom', 'nav_msgs/msg/Odometry', odometry(ts, ns, ros1), ns)
    out.close()
    return n_frames


@pytest.mark.parametrize('ros1,frame,dtype,layout,big_endian', [
    (False, 'message', np.uint16, 'range_major', False),
    (True, 'rep103', np.uint8, 'range_major', False),
    (False, 'message', np.float32, 'beam_major', False),
    (False, 'message', np.int8, 'beam_major', False),
    (True, 'message', np.int16, 'range_major', True),
    (False, 'rep103', np.uint32, 'range_major', False),
    (False, 'message', np.int32, 'beam_major', True),
    (False, 'message', np.uint64, 'range_major', False),
    (True, 'message', np.int64, 'range_major', False),
    (False, 'message', np.float64, 'beam_major', True),
])
def test_projected_sonar_image(tmp_path, ros1, frame, dtype, layout, big_endian):
    src = tmp_path / ('in.bag' if ros1 else 'in')
    n = write_projected(src, ros1, frame, dtype, layout, big_endian=big_endian)
    args = [src, '-o', tmp_path / 'out', '--image-layout', layout]
    assert run(*args) == 0
    sectors, poses = read_output(tmp_path / 'out')
    assert len(sectors) == n and len(poses) == n
    g = sectors[0][1]
    assert g.n_beams == 96 and g.ping_period == 0.0
    assert math.isclose(g.angle_min, -math.radians(65), abs_tol=1e-4)
    assert sectors[0][3] == {np.uint8: 'mono8', np.uint16: 'mono16'}.get(dtype, '32FC1')
    # The values are display-like counts scaled to the type's full scale (kept as they are, or as
    # float32 for types without an image encoding): decode as dB over that scale.
    from sonar_tracking.core.intensity import decode
    full = FULL_SCALE.get(dtype, 255.0)
    peak = max(float(np.max(a)) for a, *_ in sectors)
    assert 200 / 255 * full <= peak <= full     # the target's counts came through at their scale
    decoded = [(decode(a, 'db', db_span=60.0, full_scale=full), g2, s, e) for a, g2, s, e in sectors]
    check_target(decoded, poses)


# -- Ping Viewer logs ------------------------------------------------------------------------------

def qstring(text: str) -> bytes:
    data = text.encode('utf-16-be')   # QDataStream writes QString as UTF-16, length in bytes
    return struct.pack('>I', len(data)) + data


def write_pingviewer(path: Path, clockwise_grads: bool = True, drop_last_bytes: int = 0) -> list[tuple[int, float]]:
    from brping import PingMessage
    rng = np.random.default_rng(7)
    sample_period = int(round(2 * BIN / 1500 / 25e-9))  # 25 ns ticks for BIN metres per sample
    blob = qstring('PingViewer sensor log file') + struct.pack('>i', 1)
    for s in ('abc123', '2024-05-06', 'v2.3', 'Linux', '6'):
        blob += qstring(s)
    blob += struct.pack('>ii', 1, 2)
    pings = []
    day = 1714953600 * 10**9  # 2024-05-06 00:00 UTC
    for k, b in enumerate(head_bearings('continuous')):
        grads = int(round((-b if clockwise_grads else b) * 200 / math.pi)) % 400
        b_exact = math.remainder((-1 if clockwise_grads else 1) * grads * math.pi / 200, 2 * math.pi)
        m = PingMessage(2300)
        m.mode, m.gain_setting, m.angle, m.transmit_duration = 1, 0, grads, 20
        m.sample_period, m.transmit_frequency, m.number_of_samples = sample_period, 750, N_BINS
        m.data = bytearray(ping_samples(b_exact, rng).tobytes())
        m.data_length = N_BINS
        m.pack_msg_data()
        tod_ms = 10 * 3600 * 1000 + k * 20
        text = f'{tod_ms // 3600000:02d}:{tod_ms // 60000 % 60:02d}:{tod_ms // 1000 % 60:02d}.{tod_ms % 1000:03d}'
        blob += qstring(text) + struct.pack('>I', len(m.msg_data)) + bytes(m.msg_data)
        pings.append((day + tod_ms * 10**6, b_exact))
    path.write_bytes(blob[:len(blob) - drop_last_bytes] if drop_last_bytes else blob)
    return pings


def test_ping_viewer_log(tmp_path):
    src = tmp_path / 'ping360_20240506_100000.bin'
    pings = write_pingviewer(src)
    # Ping Viewer's head angle grows clockwise; its 0 grad points forward.
    assert run(src, '-o', tmp_path / 'out', '--preset', 'ping360') == 0
    sectors, poses = read_output(tmp_path / 'out')
    assert not poses
    assert_every_ping_once(sectors, pings, t0=1714953600 * 10**9)
    g = sectors[0][1]
    assert math.isclose(g.range_min, 0.5 * BIN, rel_tol=1e-3) and g.n_bins == N_BINS
    (rx, ry, bearing), cell = fls_target(sectors, [], decode_db=60.0)
    tx, ty = TARGET_RANGE * math.cos(TARGET_BEARING), TARGET_RANGE * math.sin(TARGET_BEARING)
    assert math.hypot(rx - tx, ry - ty) <= cell
    assert bearing > 0


def test_cut_off_ping_viewer_log(tmp_path, capsys):
    src = tmp_path / 'ping360_20240506_100000.bin'
    pings = write_pingviewer(src, drop_last_bytes=100)
    assert run(src, '-o', tmp_path / 'out', '--preset', 'ping360') == 1
    assert 'the file is cut off' in capsys.readouterr().err
    sectors, _ = read_output(tmp_path / 'out')
    assert_every_ping_once(sectors, pings[:-1], t0=1714953600 * 10**9)


ARABIC_INDIC = str.maketrans('0123456789.', '\u06f0\u06f1\u06f2\u06f3\u06f4\u06f5\u06f6\u06f7\u06f8\u06f9\u066b')


def write_pingviewer_as_logged(path: Path, digits: str = 'arabic', seed: int = 31) -> list[tuple[int, float, int]]:
    """A Ping Viewer log written the way the logger writes it: the sensor's byte stream (pings, and a
    device_information message) cut into records at random byte boundaries, each record stamped with
    the time its last byte arrived, written in Extended Arabic-Indic digits (``digits='none'``: a
    time no reader can read; ``'some'``: that for some records). The range changes after 120 pings:
    sample period and count differ and the pings turn to auto_device_data (2301). Returns
    (arrival_ns, bearing, sample period) per ping."""
    from brping import PingMessage
    rng = np.random.default_rng(seed)
    day = 1714953600 * 10**9  # 2024-05-06 00:00 UTC
    info = PingMessage(4)
    info.device_type, info.device_revision, info.firmware_version_major = 2, 1, 3
    info.pack_msg_data()
    stream, arrivals, pings = bytearray(info.msg_data), [(len(info.msg_data), 36_000_000)], []
    for k, b in enumerate(head_bearings('continuous')):
        grads = int(round(-b * 200 / math.pi)) % 400
        b_exact = math.remainder(-grads * math.pi / 200, 2 * math.pi)
        period, n = (2667, N_BINS) if k < 120 else (1600, 150)      # 10 m, then 4.8 m
        m = PingMessage(2300 if k < 120 else 2301)
        m.mode, m.gain_setting, m.angle, m.transmit_duration = 1, 0, grads, 20
        m.sample_period, m.transmit_frequency, m.number_of_samples = period, 750, n
        if k >= 120:
            m.start_angle, m.stop_angle, m.num_steps, m.delay = 0, 399, 1, 0
        m.data = bytearray(ping_samples(b_exact, rng, n).tobytes())
        m.data_length = n
        m.pack_msg_data()
        stream += m.msg_data
        tod_ms = 36_000_000 + 20 + k * 20
        arrivals.append((len(stream), tod_ms))
        pings.append((day + tod_ms * 10**6, b_exact, period))
    cuts = np.cumsum(rng.integers(1, 1500, len(stream)))
    cuts = [0] + [int(c) for c in cuts[cuts < len(stream)]] + [len(stream)]
    blob = qstring('PingViewer sensor log file') + struct.pack('>i', 1)
    for s in ('abc123', '2024-05-06', 'v2.1', 'Windows', '10'):
        blob += qstring(s)
    blob += struct.pack('>ii', 1, 2)
    for a, z in zip(cuts[:-1], cuts[1:]):
        tod_ms = next(t for end, t in arrivals if end >= z)     # when the record's last byte came
        text = f'{tod_ms // 3600000:02d}:{tod_ms // 60000 % 60:02d}:{tod_ms // 1000 % 60:02d}.{tod_ms % 1000:03d}'
        unreadable = digits == 'none' or (digits == 'some' and a % 7 == 3)
        text = '--:--:--' if unreadable else text.translate(ARABIC_INDIC)
        blob += qstring(text) + struct.pack('>I', z - a) + bytes(stream[a:z])
    path.write_bytes(blob)
    return pings


def test_ping_viewer_log_as_the_logger_writes_it(tmp_path, capsys):
    """Messages split across records at arbitrary bytes, times in Extended Arabic-Indic digits, a
    range change part-way: every ping is imported once, and no sector mixes the two settings."""
    src = tmp_path / 'ping360_20240506_100000.bin'
    pings = write_pingviewer_as_logged(src)
    assert run(src, '-o', tmp_path / 'out') == 0, capsys.readouterr().err
    sectors, _ = read_output(tmp_path / 'out')
    # Every ping once, in order; a column's time (stamp + j * ping period) is within a few pings of
    # when the ping arrived (a ping takes the time of the record its first byte is in, ms resolution).
    cols = columns(sectors, t0=0)
    assert len(cols) == len(pings)
    assert np.allclose([b for _, b in cols], [b for _, b, _ in pings], atol=1e-6)
    assert np.max(np.abs(np.array([t for t, _ in cols]) - np.array([t / 1e9 for t, _, _ in pings]))) < 0.1
    steps = {p: 1500 * p * 25e-9 / 2 for p in (2667, 1600)}
    kinds = [min(steps, key=lambda p: abs(g.range_resolution - steps[p])) for _, g, _, _ in sectors]
    for (_, g, _, _), p in zip(sectors, kinds):   # a sector's bins are those of one setting
        assert g.n_bins == (N_BINS if p == 2667 else 150)
        assert math.isclose(g.range_max, (g.n_bins - 0.5) * steps[p], rel_tol=1e-6)
    assert sum(g.n_beams for (_, g, _, _), p in zip(sectors, kinds) if p == 2667) == 120
    assert sum(g.n_beams for (_, g, _, _), p in zip(sectors, kinds) if p == 1600) == len(pings) - 120
    # Ping360 conventions from the format: the target is to port, as recorded.
    first = [x for x, p in zip(sectors, kinds) if p == 2667]
    (rx, ry, bearing), cell = fls_target(first, [], decode_db=60.0)
    tx, ty = TARGET_RANGE * math.cos(TARGET_BEARING), TARGET_RANGE * math.sin(TARGET_BEARING)
    assert math.hypot(rx - tx, ry - ty) <= cell and bearing > 0


def test_ping_viewer_records_with_unreadable_times_take_the_previous_time(tmp_path, capsys):
    src = tmp_path / 'ping360_20240506_100000.bin'
    pings = write_pingviewer_as_logged(src, digits='some')
    assert run(src, '-o', tmp_path / 'out') == 1
    err = capsys.readouterr().err
    assert re.search(r'warning: ping360 @ -: \d+ of \d+ record times cannot be read', err), err
    cols = columns(read_output(tmp_path / 'out')[0], t0=0)
    assert len(cols) == len(pings)
    assert np.allclose([b for _, b in cols], [b for _, b, _ in pings], atol=1e-6)
    assert np.max(np.abs(np.array([t for t, _ in cols]) - np.array([t / 1e9 for t, _, _ in pings]))) < 0.1


def test_ping_viewer_log_without_readable_times_is_stamped_by_sample_timing(tmp_path, capsys):
    src = tmp_path / 'ping360_20240506_100000.bin'
    pings = write_pingviewer_as_logged(src, digits='none')
    assert run(src, '-o', tmp_path / 'out') == 1
    err = capsys.readouterr().err
    assert 'no record time can be read: pings are stamped in order' in err
    sectors, _ = read_output(tmp_path / 'out')
    cols = columns(sectors, t0=1714953600 * 10**9)
    assert len(cols) == len(pings)
    # In ping order at the ping's listening time plus its 20 us transmission.
    listen = [20e-6 + (N_BINS * 2667 if p == 2667 else 150 * 1600) * 25e-9 for _, _, p in pings]
    assert np.allclose([t for t, _ in cols], np.concatenate([[0.0], np.cumsum(listen)[:-1]]), atol=1e-6)
    assert np.allclose([b for _, b in cols], [b for _, b, _ in pings], atol=1e-6)


# -- folders of polar frames ------------------------------------------------------------------------

@pytest.mark.parametrize('suffix', ['png', 'npy'])
def test_folder_of_frames(tmp_path, suffix):
    import cv2
    import yaml
    rng = np.random.default_rng(9)
    folder = tmp_path / 'frames'
    folder.mkdir()
    n_beams = 81
    bearings = np.linspace(math.radians(60), math.radians(-60), n_beams)  # column 0 at port: decreasing
    for k in range(3):
        v = rng.integers(30, 60, (N_BINS, n_beams)).astype(np.uint8)
        j = int(np.argmin(np.abs(bearings - TARGET_BEARING)))
        v[TARGET_BIN - 1:TARGET_BIN + 2, j - 1:j + 2] = 200
        v = v[::-1]  # far range in the top row, as images are usually drawn
        if suffix == 'png':
            cv2.imwrite(str(folder / f'f{k:03d}.png'), v)
        else:
            np.save(folder / f'f{k:03d}.npy', v)
    (folder / 'sonar.yaml').write_text(yaml.safe_dump({
        'angle_min_deg': 60.0, 'angle_max_deg': -60.0, 'range_min': 0.5 * BIN, 'range_max': (N_BINS - 0.5) * BIN,
        'rows': 'far_first', 'start_time': T0 / 1e9, 'frame_period': 0.2}))
    assert run(folder, '-o', tmp_path / 'out') == 0
    sectors, _ = read_output(tmp_path / 'out')
    assert len(sectors) == 3 and sectors[0][1].angle_increment > 0
    (x, y, bearing), cell = fls_target(sectors, [], decode_db=60.0)
    assert math.hypot(x - TARGET_RANGE * math.cos(TARGET_BEARING), y - TARGET_RANGE * math.sin(TARGET_BEARING)) <= cell


# -- inspect and bad input ----------------------------------------------------------------------------

def test_inspect_lists_topics_and_writes_nothing(tmp_path, capsys):
    write_scanning(tmp_path / 'in.bag', 'scanline', 'sector', True, ros1=True)
    assert run(tmp_path / 'in.bag', '--inspect', '--clockwise', '--head-zero', 180) == 0
    out = capsys.readouterr().out
    assert '/sonar/raw' in out and 'micron_test/msg/ScanLine' in out and 'scan lines -> sectors' in out
    assert '/nav/odom' in out and '/platform/odometry' in out
    assert 'would write 4 sectors' in out
    assert not (tmp_path / 'out').exists()


def test_cut_off_bag_imports_up_to_the_cut(tmp_path, capsys):
    pings = write_scanning(tmp_path / 'in', 'echo_rad', 'continuous', False, ros1=False)
    mcap = next((tmp_path / 'in').glob('*.mcap'))
    data = mcap.read_bytes()
    mcap.write_bytes(data[: int(len(data) * 0.6)])
    (tmp_path / 'in' / 'metadata.yaml').unlink()
    assert run(tmp_path / 'in', '-o', tmp_path / 'out') == 1
    assert 'cut off' in capsys.readouterr().err
    sectors, _ = read_output(tmp_path / 'out')
    cols = columns(sectors)
    assert 0 < len(cols) < len(pings)
    # What was imported is a prefix of the recording, each ping once.
    assert_every_ping_once(sectors, pings[:len(cols)])


@pytest.mark.parametrize('chunk_bytes', [0, 30_000], ids=['one-cut-chunk', 'chunks'])
def test_ros1_bag_without_index_imports_up_to_the_cut(tmp_path, capsys, chunk_bytes):
    """A ROS 1 bag whose recorder was killed (no index, the last chunk cut) is read record by record."""
    pings = write_scanning(tmp_path / 'in.bag', 'echo_grad', 'continuous', False, ros1=True, chunk_bytes=chunk_bytes)
    data = (tmp_path / 'in.bag').read_bytes()
    (tmp_path / 'in.bag').write_bytes(data[: int(len(data) * 0.6)])
    assert run(tmp_path / 'in.bag', '-o', tmp_path / 'out') == 1
    assert 'has no index' in capsys.readouterr().err
    sectors, poses = read_output(tmp_path / 'out')
    cols = columns(sectors)
    assert 0.4 * len(pings) < len(cols) < 0.7 * len(pings) and poses
    assert_every_ping_once(sectors, pings[:len(cols)])


def test_bad_messages_are_reported_and_the_rest_imported(tmp_path, capsys):
    """Pings with missing samples, a time gap, missing pings, a ping recorded twice, an undecodable
    message and a topic of unknown type: each named with topic and stamp, everything else imported
    once, exit code 1."""
    ts = typestore(False, {'ping_test/msg/SonarEcho': ECHO_DEF})
    out = BagOut(tmp_path / 'in', False, ts)
    out.conns['/mystery'] = out.w.add_connection('/mystery', 'nobody_msgs/msg/Thing', msgdef='',
                                                 rihs01='RIHS01_' + '0' * 64)
    rng = np.random.default_rng(11)
    bearings = list(STEP * np.arange(60))
    del bearings[30:33]                       # three pings missing
    pings, t = [], T0
    for k, b in enumerate(bearings):
        t += PERIOD_NS if k != 45 else 5 * 10**9   # a 5 s gap before ping 45
        s = ping_samples(b, rng)
        if k == 10:
            s = s[:150]                       # 50 samples missing
        msg = new(ts, 'ping_test/msg/SonarEcho', header=header(ts, t, False), angle=float(b), number_of_samples=N_BINS,
                  range=int(N_BINS * BIN), intensities=s)
        out.write('/ping360/echo', 'ping_test/msg/SonarEcho', msg, t)
        pings.append((t, float(b)))
        if k == 50:
            out.write('/ping360/echo', 'ping_test/msg/SonarEcho', msg, t + 3)  # recorded twice
        if k == 20:
            out.write_raw('/ping360/echo', b'\x00\x01\x00\x00\x07', t + 1)   # not a SonarEcho
            out.write_raw('/mystery', b'\x00\x01\x00\x00', t + 2)
    out.close()
    assert run(tmp_path / 'in', '-o', tmp_path / 'out') == 1
    err = capsys.readouterr().err
    stamp = lambda ns: f'{ns // 10**9}.{ns % 10**9:09d}'  # noqa: E731
    assert f'/ping360/echo @ {stamp(pings[10][0])}: ping has 150 of its 200 samples' in err
    assert f'/ping360/echo @ {stamp(pings[30][0])}: bearing jumped' in err and 'about 3 pings missing' in err
    assert f'/ping360/echo @ {stamp(pings[45][0])}: 5.000 s since the previous ping' in err
    assert f'/ping360/echo @ {stamp(pings[20][0] + 1)}: message cannot be decoded' in err
    assert '/mystery' in err and 'type unknown' in err
    assert f'/ping360/echo @ {stamp(pings[50][0])}: the same ping again' in err
    sectors, _ = read_output(tmp_path / 'out')
    assert_every_ping_once(sectors, pings)
    # The short ping's column holds its 150 samples and 50 zeros (nothing measured) beyond them.
    t10 = (pings[10][0] - T0) / 1e9
    a, g, stamp, _ = next(x for x in sectors if any(abs(c[0] - t10) < 1e-6 for c in columns([x])))
    j = int(round((t10 - (stamp - T0) / 1e9) / g.ping_period))
    assert a[150:, j].max() == 0 and a[:150, j].min() > 0


def test_nothing_to_import_exits_2(tmp_path, capsys):
    assert run(tmp_path / 'missing.bag', '-o', tmp_path / 'out') == 2
    ts = typestore(False)
    out = BagOut(tmp_path / 'odo', False, ts)
    out.write('/nav/odom', 'nav_msgs/msg/Odometry', odometry(ts, T0, False), T0)
    out.close()
    assert run(tmp_path / 'odo', '-o', tmp_path / 'out') == 2
    assert 'no sonar topic recognised' in capsys.readouterr().err
    assert not (tmp_path / 'out').exists()


def test_picture_of_a_recorded_run(tmp_path):
    """--picture draws what a stack recorded: the last FLS image with its regions, track trails, path."""
    from sonar_tracking.core.fls.grid import ImageGrid
    from sonar_tracking.core.records import GPF_TRACK_DTYPE, REGION_DTYPE
    from sonar_tracking.msgs.map_info import grid_to_map_info
    ts = typestore(False)
    types = ma.RosbagsTypes(ts)
    out = BagOut(tmp_path / 'run', False, ts)
    grid = ImageGrid(resolution=0.1, width=120, height=80, origin_x=-2.0, origin_y=-4.0, origin_yaw=0.3)
    for k in range(3):
        ns = T0 + k * 10**9
        image = np.ones(grid.shape, np.float32)
        image[40:43, 60:63] = 30.0
        out.write('/fls/image', 'sensor_msgs/msg/Image', ma.array_to_image(image, stamp_ns=ns, frame_id='world',
                                                                           types=types), ns)
        out.write('/fls/image_info', 'nav_msgs/msg/MapMetaData', grid_to_map_info(grid, ns, types), ns)
        regions = np.zeros(2, REGION_DTYPE)
        regions['x'], regions['y'] = (1.0, 2.0), (0.5, -1.0)
        out.write('/fls/regions', 'sensor_msgs/msg/PointCloud2', ma.array_to_cloud(regions, stamp_ns=ns, types=types),
                  ns)
        tracks = np.zeros(1, GPF_TRACK_DTYPE)
        tracks['track_id'], tracks['x'], tracks['y'] = 7, 1.0 + 0.1 * k, 0.5
        out.write('/gpf/tracks', 'sensor_msgs/msg/PointCloud2', ma.array_to_cloud(tracks, stamp_ns=ns, types=types), ns)
        out.write('/platform/odometry', 'nav_msgs/msg/Odometry', odometry(ts, ns, False), ns)
    out.close()
    png = tmp_path / 'run.png'
    assert run(tmp_path / 'run', '--picture', '-o', png) == 0
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    from sonar_tracking.cli.import_picture import draw_run
    assert draw_run(tmp_path / 'run', tmp_path / 'again.png') == {
        'image': 1, 'regions': 2, 'gpf_tracks': 1, 'tracks': 0, 'detections': 0, 'poses': 3}
