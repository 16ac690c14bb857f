"""sonar_echo: the table, CSV and JSON formatting (no ROS), and the tool on live topics over DDS."""
from __future__ import annotations

import csv
import io
import json
import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking import process
from sonar_tracking.cli.sonar_echo import (
    WIDTH,
    EchoError,
    csv_header,
    csv_rows,
    format_table,
    json_line,
    record_fields,
    table_columns,
)


def tracks() -> np.ndarray:
    """Five IMM-IPDA tracks, three confirmed, with values whose shortest repr is long."""
    r = np.zeros(5, ma.TRACK_DTYPE)
    r['track_id'] = [7, 3, 12, 5, 40]
    r['x'] = [100.123456789, -2.5, 3000.0, 1 / 3, 0.1 + 0.2]
    r['y'] = [-1e-300, 1.1, 2.2, 3.3, 2345.678]
    r['vx'] = [3.0, 0.0, -1.0, 0.0, 0.0]
    r['vy'] = [4.0, 1.0, 0.0, 0.0, -2.0]
    r['existence'] = [0.99, 0.5, 0.9734, 0.1, 0.2]
    r['confirmed'] = [1, 0, 1, 0, 1]
    r['cov_xx'] = [np.pi, 2.0, 3.0, 4.0, 1e-12]
    return r


def rows_of(lines):
    """The data rows of a table (after the title and the column titles), split into cells."""
    return [line.split() for line in lines[2:]]


def test_tracks_table_shows_confirmed_tracks_by_id_with_speed_and_course():
    columns, dropped = table_columns(ma.TRACK_DTYPE)
    assert [c.name for c in columns] == ['track_id', 'x', 'y', 'speed', 'course', 'existence'] and not dropped
    lines = format_table(tracks(), columns, title='/tracks')
    assert lines[0] == '/tracks  3 confirmed of 5 records'
    assert lines[1].split() == ['id', 'x[m]', 'y[m]', 'speed[m/s]', 'course[deg]', 'existence']
    assert rows_of(lines) == [['7', '100.12', '-0.00', '5.00', '53.1', '0.990'],
                              ['12', '3000.00', '2.20', '1.00', '180.0', '0.973'],
                              ['40', '0.30', '2345.68', '2.00', '-90.0', '0.200']]
    assert max(map(len, lines)) <= WIDTH


def test_all_adds_tentative_tracks_after_the_confirmed_ones():
    columns, _ = table_columns(ma.TRACK_DTYPE, show_all=True)
    assert columns[-1].name == 'confirmed'
    lines = format_table(tracks(), columns, show_all=True)
    assert lines[0] == '5 records'
    assert [(r[0], r[-1]) for r in rows_of(lines)] == [('7', 'yes'), ('12', 'yes'), ('40', 'yes'), ('3', 'no'),
                                                       ('5', 'no')]


def test_rows_are_limited_and_the_rest_counted():
    columns, _ = table_columns(ma.TRACK_DTYPE, show_all=True)
    lines = format_table(tracks(), columns, show_all=True, max_rows=2)
    assert len(rows_of(lines)) == 3 and lines[-1] == '... 3 more (--rows)'


def test_gpf_tracks_show_the_fusion_and_other_records_their_positions():
    columns, _ = table_columns(ma.GPF_TRACK_DTYPE)
    assert [c.name for c in columns] == ['track_id', 'x', 'y', 'speed', 'course', 'fusion']
    r = np.zeros(2, ma.GPF_TRACK_DTYPE)
    r['track_id'], r['confirmed'], r['fusion'] = [1, 2], 1, [0, 1]
    assert [row[-1] for row in rows_of(format_table(r, columns))] == ['MF', 'WF']
    assert [c.name for c in table_columns(ma.DETECTION_DTYPE)[0]] == ['x', 'y', 'range', 'bearing', 'amplitude',
                                                                      'clutter_density']
    assert [c.name for c in table_columns(ma.REGION_DTYPE)[0]] == ['region_id', 'x', 'y', 'range', 'bearing']
    assert [c.name for c in table_columns(ma.TRUTH_DTYPE)[0]] == ['target_id', 'x', 'y', 'speed', 'course']
    d = np.zeros(1, ma.DETECTION_DTYPE)
    d['bearing'] = math.radians(-12.5)
    assert rows_of(format_table(d, table_columns(ma.DETECTION_DTYPE)[0]))[0][3] == '-12.5'   # degrees


def test_chosen_fields_that_do_not_fit_are_named_and_unknown_ones_refused():
    columns, dropped = table_columns(ma.REGION_DTYPE, list(ma.FEATURE_NAMES))
    assert dropped and [c.name for c in columns] + dropped == list(ma.FEATURE_NAMES)
    lines = format_table(np.zeros(3, ma.REGION_DTYPE), columns, dropped=dropped)
    assert max(map(len, lines)) <= WIDTH and dropped[0] in lines[1]
    with pytest.raises(EchoError, match='available: .*speed, course'):
        table_columns(ma.TRACK_DTYPE, ['x', 'heading'])
    with pytest.raises(EchoError, match="no field"):
        record_fields(ma.DETECTION_DTYPE, ['speed'])   # detections have no velocity


def test_csv_parses_back_to_the_same_numbers():
    r = tracks()
    names = record_fields(r.dtype)
    assert names == list(ma.TRACK_DTYPE.names)
    text = io.StringIO()
    writer = csv.writer(text, lineterminator='\n')
    writer.writerow(csv_header(names))
    writer.writerows(csv_rows(r, names, 1_700_000_000_123_456_789))
    table = list(csv.DictReader(io.StringIO(text.getvalue())))
    assert len(table) == len(r)
    for row, rec in zip(table, r):
        assert row['stamp'] == '1700000000.123456789'
        for name in names:
            assert type(rec[name].item())(row[name]) == rec[name], name


def test_json_lines_hold_the_values_and_null_for_non_finite():
    r = tracks()[:2]
    r['x'][1] = np.nan
    obj = json.loads(json_line(r, ['track_id', 'x', 'speed'], 12_000_000_001, 'world'))
    assert obj['stamp'] == 12.000000001 and obj['frame_id'] == 'world'
    assert obj['records'] == [{'track_id': 7, 'x': 100.123456789, 'speed': 5.0},
                              {'track_id': 3, 'x': None, 'speed': 1.0}]


# --- the tool on live topics -------------------------------------------------------------------


def echo(ros, topic: str, messages: list, *args: str, best_effort: bool = False, timeout: float = 40.0):
    """Run ``sonar_echo ARGS`` while the test node publishes ``messages`` on ``topic`` in turn until
    the tool exits; returns (exit status, stdout, stderr)."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import PointCloud2
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT if best_effort
                     else ReliabilityPolicy.RELIABLE)
    pub = ros.node.create_publisher(PointCloud2, topic, qos)
    proc = subprocess.Popen([sys.executable, '-m', 'sonar_tracking.cli.sonar_echo', *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=process.child_dies_with_parent())
    try:
        ros.wait(lambda: pub.get_subscription_count() > 0 or proc.poll() is not None, timeout,
                 'sonar_echo to subscribe')
        deadline, k = time.monotonic() + timeout, 0
        while proc.poll() is None and time.monotonic() < deadline:
            pub.publish(messages[k % len(messages)])
            k += 1
            try:
                proc.wait(0.2)   # the next message only if this one did not end it
            except subprocess.TimeoutExpired:
                pass
        out, err = proc.communicate(timeout=10)
        return proc.returncode, out, err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        ros.node.destroy_publisher(pub)


def clouds(records, n: int, t0_ns: int = 1_700_000_000_000_000_001) -> list:
    return [ma.array_to_cloud(records, stamp_ns=t0_ns + k * 10**9, frame_id='world') for k in range(n)]


@pytest.mark.ros
def test_table_of_tracks_in_a_namespace(ros):
    ns = f'/echo{os.getpid()}'
    code, out, err = echo(ros, f'{ns}/tracks', clouds(tracks(), 1), 'tracks', '--once',
                          '--ros-args', '-r', f'__ns:={ns}')
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0] == f'{ns}/tracks  stamp 1700000000.000000001  frame world  3 confirmed of 5 records'
    assert rows_of(lines) == rows_of(format_table(tracks(), table_columns(ma.TRACK_DTYPE)[0]))
    assert [r[0] for r in rows_of(lines)] == ['7', '12', '40']


@pytest.mark.ros
def test_csv_from_a_best_effort_publisher_parses_back_to_the_records(ros):
    topic = f'/echo{os.getpid()}/gpf/tracks'
    r = np.zeros(3, ma.GPF_TRACK_DTYPE)
    r['track_id'], r['confirmed'], r['fusion'] = [4, 9, 2], [1, 0, 1], [1, 0, 0]
    r['x'], r['y'] = [1 / 7, -1e-17, 12345.678901234567], [2 / 3, 5e300, -0.1]
    r['vx'], r['vy'], r['cov_vyvy'] = [1.5, 0.0, -3.0], [2.0, 0.0, 4.0], [np.e, 0.0, 1e-9]
    msgs = clouds(r, 5)
    code, out, err = echo(ros, topic, msgs, topic, '--csv', '--all', '--count', '2', best_effort=True)
    assert code == 0, err
    table = list(csv.DictReader(io.StringIO(out)))
    assert len(table) == 6 and list(table[0]) == ['stamp', *ma.GPF_TRACK_DTYPE.names]
    stamps = {f'{ma.header_ns(m) // 10**9}.{ma.header_ns(m) % 10**9:09d}' for m in msgs}
    for i, row in enumerate(table):
        assert row['stamp'] in stamps
        for name in ma.GPF_TRACK_DTYPE.names:
            assert type(r[i % 3][name].item())(row[name]) == r[i % 3][name], name
    # Without --all only the confirmed tracks, and the derived fields on request.
    code, out, err = echo(ros, topic, msgs, topic, '--json', '--once', '--fields', 'track_id,speed,fusion')
    assert code == 0, err
    assert json.loads(out)['records'] == [{'track_id': 4, 'speed': 2.5, 'fusion': 1},
                                          {'track_id': 2, 'speed': 5.0, 'fusion': 0}]


@pytest.mark.ros
def test_a_topic_that_is_not_a_cloud_is_refused(ros):
    from std_msgs.msg import Float64
    topic = f'/echo{os.getpid()}/threshold'
    pub = ros.node.create_publisher(Float64, topic, 10)
    try:
        r = subprocess.run([sys.executable, '-m', 'sonar_tracking.cli.sonar_echo', topic, '--once',
                            '--timeout', '30'], capture_output=True, text=True, timeout=60)
    finally:
        ros.node.destroy_publisher(pub)
    assert r.returncode == 2 and 'std_msgs/msg/Float64, not sensor_msgs/msg/PointCloud2' in r.stderr
