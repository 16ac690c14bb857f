"""sonar_import on input that is not what it claims to be: a clear message, the documented exit code
(2: nothing imported; 1: imported with problems), and nothing half-written at the output."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from sonar_tracking.cli.sonar_import import main as sonar_import
from sonar_tracking.io.bags import MCAP_MAGIC, read_bag


def run(capsys, *args) -> tuple[int, str]:
    code = sonar_import([str(a) for a in args])
    return code, capsys.readouterr().err


def leftovers(folder: Path) -> list[str]:
    """Names in ``folder`` an import may have left (its output, or a hidden folder it built it in)."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(('out', '.out')))


GEOMETRY = {'angle_min_deg': -30.0, 'angle_max_deg': 30.0, 'range_min': 1.0, 'range_max': 10.0,
            'start_time': 1_700_000_000.0, 'frame_period': 0.1}


def frames(folder: Path, values: list[np.ndarray], meta: dict | bytes | None = None) -> Path:
    """A folder of ``.npy`` frames with its sonar.yaml (``meta``: settings, or the file's raw bytes)."""
    folder.mkdir()
    for k, v in enumerate(values):
        np.save(folder / f'f{k:03d}.npy', v)
    text = meta if isinstance(meta, bytes) else yaml.safe_dump(GEOMETRY if meta is None else meta).encode()
    (folder / 'sonar.yaml').write_bytes(text)
    return folder


def echo_frames(rng: np.random.Generator, n: int = 3) -> list[np.ndarray]:
    return [rng.uniform(0.0, 1.0, (40, 16)).astype(np.float32) for _ in range(n)]


@pytest.mark.parametrize('name,content,said', [
    ('random.bag', 'random', 'not a readable ROS 1 bag'),
    ('magic.bag', 'ros1-magic', 'no sonar topic recognised'),
    ('magic.mcap', 'mcap-magic', 'holds no topic'),
    ('empty.mcap', b'', 'holds no topic'),
])
def test_files_that_are_not_recordings_exit_2_with_nothing_written(tmp_path, capsys, name, content, said):
    rng = np.random.default_rng(3)
    data = {'random': rng.bytes(5000), 'ros1-magic': b'#ROSBAG V2.0\n' + rng.bytes(20000),
            'mcap-magic': MCAP_MAGIC}.get(content, content)
    (tmp_path / name).write_bytes(data)
    code, err = run(capsys, tmp_path / name, '-o', tmp_path / 'out')
    assert code == 2 and said in err and err.startswith('error: '), err
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize('meta,said', [
    ({**GEOMETRY, 'start_time': 1e300}, 'start_time = 1e+300 is outside'),
    (yaml.safe_dump({**GEOMETRY, 'start_time': 0}).replace('start_time: 0', 'start_time: 1e300').encode(),
     'start_time = 1e+300 is outside'),            # YAML 1.1 reads this 1e300 as text
    ({**GEOMETRY, 'rows': 'sideways'}, "rows = 'sideways' must be near_first or far_first"),
    (yaml.safe_dump(GEOMETRY).encode() + b'frame_id: caf\xe9\n', 'is not UTF-8 text'),
    ({**GEOMETRY, 'range_min': 'near'}, "range_min = 'near' is not a number"),
    ({**GEOMETRY, 'stamps': [1.0, float('nan'), 3.0]}, 'stamps[1] = nan is not a time'),
    ({**GEOMETRY, 'frame_period': -1.0}, 'frame_period = -1.0 is outside'),
    (b'- a list\n- of things\n', 'must be a mapping'),
], ids=['start_time-1e300', 'start_time-1e300-text', 'rows-sideways', 'not-utf8', 'range-not-a-number',
        'nan-stamp', 'negative-period', 'not-a-mapping'])
def test_bad_sonar_yaml_exits_2_naming_the_setting(tmp_path, capsys, meta, said):
    folder = frames(tmp_path / 'in', echo_frames(np.random.default_rng(4)), meta)
    code, err = run(capsys, folder, '-o', tmp_path / 'out')
    assert code == 2 and said in err and err.startswith('error: '), err
    assert leftovers(tmp_path) == []


FAN = {'image': 'fan', 'apex_px': [8, 39], 'metres_per_pixel': 0.25, 'fov_deg': 60.0, 'range_min': 1.0,
       'range_max': 9.0, 'start_time': 1_700_000_000.0}
TABLE = {k: v for k, v in GEOMETRY.items() if not k.startswith('angle')}


@pytest.mark.parametrize('meta,files,said', [
    ({**TABLE, 'beam_angles_deg': 'angles.csv'}, {'angles.csv': 'angle\n1\n2\nx\n'},
     "line 4 of angles.csv ('x') does not end in an angle"),
    ({**TABLE, 'beam_angles_deg': 'angles.csv'}, {'angles.csv': '\n'.join(map(str, [1, 2, 2, *range(3, 16)]))},
     'the angles must grow (or fall) from beam to beam; beam 3 (2 deg) follows beam 2 (2 deg)'),
    ({**TABLE, 'beam_angles_deg': list(range(10))}, {}, 'beam_angles_deg has 10 angles but f000.npy has 16 columns'),
    ({**TABLE, 'beam_angles_deg': 'missing.csv'}, {}, 'missing.csv does not exist'),
    ({**TABLE, 'beam_angles_deg': [0, 1, 'wide']}, {}, "beam_angles_deg[2] = 'wide' is not a number"),
    ({**GEOMETRY, 'beam_angles_deg': list(range(16))}, {}, 'give one or the other'),
    ({**GEOMETRY, 'stamps': 'names'}, {}, 'stamps: names, but f000.npy holds no date-time'),
    ({**GEOMETRY, 'stamps': 'times.csv'}, {'times.csv': 'f000.npy,1700000000.0\nf002.npy,1700000000.2\n'},
     'times.csv has no row for f001.npy'),
    ({**GEOMETRY, 'stamps': 'times.csv'}, {'times.csv': 'file,time\nf000.npy,1700000000.0\nf001.npy,soon\n'},
     "line 3 of times.csv ('f001.npy,soon') does not end in a time"),
    ({**GEOMETRY, 'stamps': 'times.csv'}, {'times.csv': '1700000000.0\n'}, 'times.csv has 1 times for 3 frames'),
    ({**FAN, 'apex_px': [8]}, {}, 'apex_px = [8] must be [column, row]'),
    ({**FAN, 'forward': 'sideways'}, {}, "forward = 'sideways' must be one of"),
    ({**FAN, 'metres_per_pixel': 0.0}, {}, 'metres_per_pixel = 0 must be more than 0'),
    ({**FAN, 'metres_per_pixel': 1e-5}, {}, 'more than 16000000 cells'),
    ({**FAN, 'fan_beams': 1}, {}, 'fan_beams = 1 must be a whole number of at least 2'),
    ({**FAN, 'fov_deg': 60.0, 'angle_min_deg': -30.0}, {}, 'give fov_deg or angle_min_deg and angle_max_deg'),
    ({**GEOMETRY, 'beam_angle_deg': [1, 2]}, {}, "unknown setting(s) ['beam_angle_deg']"),
    ({**GEOMETRY, 'image': 'cartesian'}, {}, "image = 'cartesian' must be polar"),
], ids=['table-not-a-number', 'table-not-monotone', 'table-count', 'table-missing', 'table-list-entry',
        'table-and-limits', 'names-without-time', 'csv-missing-row', 'csv-bad-time', 'csv-count', 'fan-apex',
        'fan-forward', 'fan-scale-zero', 'fan-too-many-cells', 'fan-beams-1', 'fan-fov-and-limits', 'typo',
        'image-kind'])
def test_bad_frame_settings_exit_2_naming_them(tmp_path, capsys, meta, files, said):
    folder = frames(tmp_path / 'in', echo_frames(np.random.default_rng(4)), meta)
    for name, text in files.items():
        (folder / name).write_text(text)
    code, err = run(capsys, folder, '-o', tmp_path / 'out')
    assert code == 2 and said in err and err.startswith('error: '), err
    assert leftovers(tmp_path) == []


def test_a_folder_of_frames_without_sonar_yaml_says_so(tmp_path, capsys):
    folder = frames(tmp_path / 'in', echo_frames(np.random.default_rng(4), 2))
    (folder / 'sonar.yaml').unlink()
    code, err = run(capsys, folder, '-o', tmp_path / 'out')
    assert code == 2 and 'holds 2 frame files but no sonar.yaml describing their geometry' in err, err
    assert 'no sonar topic' not in err
    (tmp_path / 'empty').mkdir()
    code, err = run(capsys, tmp_path / 'empty', '-o', tmp_path / 'out')
    assert code == 2 and 'is neither a ROS 2 bag' in err and 'nor a folder of frames' in err, err
    assert leftovers(tmp_path) == []


def test_colour_frames_are_skipped_with_the_reason(tmp_path, capsys):
    import cv2
    folder = frames(tmp_path / 'in', [])
    rng = np.random.default_rng(7)
    grey = rng.integers(0, 255, (40, 16), dtype=np.uint8)
    cv2.imwrite(str(folder / 'f000.png'), np.dstack([grey] * 3))                   # grey stored as colour: read
    cv2.imwrite(str(folder / 'f001.png'), rng.integers(0, 255, (40, 16, 3), dtype=np.uint8))  # a colour map
    code, err = run(capsys, folder, '-o', tmp_path / 'out')
    assert code == 1 and 'f001.png' in err and 'a colour image (its channels differ)' in err, err
    images = [m for m in read_bag(tmp_path / 'out', ['/sonar/sector'])]
    assert len(images) == 1


def test_an_all_nan_frame_is_a_problem_and_a_failed_import_leaves_nothing(tmp_path, capsys):
    rng = np.random.default_rng(5)
    nan = np.full((40, 16), np.nan, np.float32)
    folder = frames(tmp_path / 'in', [nan, nan.copy()])
    code, err = run(capsys, folder, '-o', tmp_path / 'out')
    assert code == 2, err
    assert err.count('every one of its 640 values is NaN or infinite; sector skipped') == 2
    assert 'wrote nothing: 0 sectors' in err and '2 problems' in err
    assert leftovers(tmp_path) == []
    # The rerun on repaired frames is not refused for an output the failed run left.
    good = echo_frames(rng, 2)
    for k, v in enumerate(good):
        np.save(folder / f'f{k:03d}.npy', v)
    code, err = run(capsys, folder, '-o', tmp_path / 'out')
    assert code == 0 and '0 problems' in err, err
    assert leftovers(tmp_path) == ['out']
    assert sum(m.topic == '/sonar/sector' for m in read_bag(tmp_path / 'out')) == 2


def test_nan_cells_become_zero_and_are_reported(tmp_path, capsys):
    import sonar_tracking.msgs as ma
    values = echo_frames(np.random.default_rng(6), 2)
    values[1][3, 4] = np.nan
    values[1][7, 2] = np.inf
    folder = frames(tmp_path / 'in', values)
    code, err = run(capsys, folder, '-o', tmp_path / 'out')
    assert code == 1, err
    assert 'f001.npy' not in err and '2 of its 640 values are NaN or infinite; set to 0 (no echo)' in err
    assert '1 problems' in err
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS2_JAZZY)
    images = [ma.image_to_array(ts.deserialize_cdr(m.data, 'sensor_msgs/msg/Image'))
              for m in read_bag(tmp_path / 'out', ['/sonar/sector'])]
    assert len(images) == 2 and np.array_equal(images[0], values[0])
    expected = np.where(np.isfinite(values[1]), values[1], 0.0)
    assert np.all(np.isfinite(images[1])) and np.array_equal(images[1], expected)


def projected_bag(path: Path, n: int = 3) -> None:
    """A ROS 2 bag of ``n`` ProjectedSonarImage frames (16 beams x 40 ranges, uint8)."""
    from rosbags.typesys import Stores, get_typestore

    from sonar_tracking.io.bags import BagWriter
    from sonar_tracking.io.importers.msgdefs import BUILTIN_DEFINITIONS, register_definitions
    ts = get_typestore(Stores.ROS2_JAZZY)
    register_definitions(ts, BUILTIN_DEFINITIONS)
    t, vec = ts.types, ts.types['geometry_msgs/msg/Vector3']
    rng = np.random.default_rng(9)
    az = np.radians(np.linspace(-30.0, 30.0, 16))
    w = BagWriter(path, 'mcap', sync=False)
    w.open()
    conn = w.add_connection('/oculus/image', 'marine_acoustic_msgs/msg/ProjectedSonarImage', typestore=ts)
    for k in range(n):
        ns = 1_700_000_000 * 10**9 + k * 10**8
        stamp = t['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9)
        msg = t['marine_acoustic_msgs/msg/ProjectedSonarImage'](
            header=t['std_msgs/msg/Header'](stamp=stamp, frame_id='sonar'),
            ping_info=t['marine_acoustic_msgs/msg/PingInfo'](frequency=1.2e6, sound_speed=1500.0,
                                                             tx_beamwidths=np.zeros(0, np.float32),
                                                             rx_beamwidths=np.zeros(0, np.float32)),
            beam_directions=[vec(x=0.0, y=-float(np.sin(a)), z=float(np.cos(a))) for a in az],
            ranges=np.linspace(1.0, 10.0, 40).astype(np.float32),
            image=t['marine_acoustic_msgs/msg/SonarImageData'](is_bigendian=False, dtype=0, beam_count=16,
                                                              data=rng.integers(0, 255, 640).astype(np.uint8)))
        w.write(conn, ns, ts.serialize_cdr(msg, 'marine_acoustic_msgs/msg/ProjectedSonarImage'))
    w.close()


def test_a_bag_with_metadata_that_is_not_utf8_is_read_from_its_files(tmp_path, capsys):
    projected_bag(tmp_path / 'bag')
    meta = tmp_path / 'bag' / 'metadata.yaml'
    meta.write_bytes(meta.read_bytes().replace(b'storage_identifier: mcap', b'storage_identifier: mc\xe4p'))
    code, err = run(capsys, tmp_path / 'bag', '-o', tmp_path / 'out')
    assert code == 1, err
    assert 'metadata.yaml that is not rosbag2 metadata' in err and '0 problems' not in err
    assert sum(m.topic == '/sonar/sector' for m in read_bag(tmp_path / 'out')) == 3


def test_a_failure_during_the_import_leaves_nothing(tmp_path, capsys, monkeypatch):
    """An error after sectors were written (here the writer raising at the second sector) removes the
    bag being built: the output does not exist, and a rerun is not refused."""
    from sonar_tracking.io.importers import run as run_module
    folder = frames(tmp_path / 'in', echo_frames(np.random.default_rng(8), 3))
    original = run_module.SectorBagWriter.sector
    calls = []

    def failing(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise OSError(28, 'No space left on device')
        return original(self, *args, **kwargs)
    monkeypatch.setattr(run_module.SectorBagWriter, 'sector', failing)
    code, err = run(capsys, folder, '-o', tmp_path / 'out')
    assert code == 2 and 'No space left on device' in err and 'nothing written' in err, err
    assert leftovers(tmp_path) == []
    monkeypatch.setattr(run_module.SectorBagWriter, 'sector', original)
    code, err = run(capsys, folder, '-o', tmp_path / 'out')
    assert code == 0, err
    assert sum(m.topic == '/sonar/sector' for m in read_bag(tmp_path / 'out')) == 3
