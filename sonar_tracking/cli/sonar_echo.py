"""``sonar_echo``: print one of the package's record topics as a live table, CSV or JSON lines.

Record topics are ``sensor_msgs/PointCloud2`` clouds of the dtypes in ``sonar_tracking.core.records``
(``detections``, ``tracks``, ``gpf/tracks``, ``fls/regions``, ``sonar/truth``); any PointCloud2 is
decoded by its field names (``sonar_tracking.msgs.cloud_to_array``), so no ROS command-line tool is needed::

    sonar_echo tracks                      # live table of the confirmed tracks
    sonar_echo tracks --all --once         # one table, tentative tracks too
    sonar_echo gpf/tracks --csv --count 100 > gpf.csv
    sonar_echo detections --json --fields x,y,amplitude
    sonar_echo tracks --ros-args -r __ns:=/auv1     # relative names resolve in the namespace

The table shows, for clouds with a velocity, ``id, x, y, speed, course, existence`` (IMM-IPDA) or
``fusion`` (GPF: MF or WF); course in degrees counter-clockwise from +x (REP-103), bearings in
degrees; otherwise the position fields. It fits 100 columns; ``--fields`` chooses others, among them
the derived ``speed`` and ``course``. Records with a ``confirmed`` field are shown only when
confirmed unless ``--all`` is given (in every output format). CSV has a header row and one row per
record, ``stamp`` (seconds, exact to the nanosecond) first, numbers written with Python's ``repr``
so they parse back to the same values; by default it holds every field of the record. JSON lines
give one object per message: ``stamp`` (s), ``frame_id`` and ``records`` (non-finite values as null).

The subscription's QoS follows the topic's publishers (reliable unless one of them is best effort,
transient local when all are), so the first publisher is awaited; ``--qos reliable`` or
``--qos sensor_data`` subscribe at once instead.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ['main', 'Column', 'EchoError', 'available', 'column_values', 'visible', 'table_columns',
           'format_table', 'record_fields', 'csv_header', 'csv_rows', 'json_line', 'stamp_text']

CLOUD_TYPE = 'sensor_msgs/msg/PointCloud2'
WIDTH = 100
#: Fields derived from ``vx, vy``: speed [m/s] and course [deg, counter-clockwise from +x].
DERIVED = ('speed', 'course')
_ID_FIELDS = ('track_id', 'target_id', 'region_id')


class EchoError(ValueError):
    """A field or topic that cannot be shown; the message says which and what is available."""


@dataclass(frozen=True)
class Column:
    """One table column: the field (or derived value) it shows, its title, width and formatter."""

    name: str
    title: str
    width: int
    text: Callable[[object], str]


def _num(fmt: str) -> Callable[[object], str]:
    def text(v) -> str:
        v = float(v)
        return format(v, fmt) if math.isfinite(v) else str(v)
    return text


def _column(name: str) -> Column:
    """How the table shows a field: positions to cm, angles in degrees, small values in %g."""
    if name in _ID_FIELDS:
        return Column(name, 'id', 8, lambda v: str(int(v)))
    if name in ('x', 'y', 'range'):
        return Column(name, f'{name}[m]', 11, _num('.2f'))
    if name in ('vx', 'vy', 'speed'):
        return Column(name, f'{name}[m/s]', 11, _num('.2f'))
    if name in ('course', 'bearing'):
        return Column(name, f'{name}[deg]', 12, _num('.1f'))
    if name == 'existence' or name.startswith('mode_'):
        return Column(name, name, max(9, len(name)), _num('.3f'))
    if name == 'confirmed':
        return Column(name, 'conf', 4, lambda v: 'yes' if int(v) else 'no')
    if name == 'fusion':
        return Column(name, 'fusion', 6, lambda v: {0: 'MF', 1: 'WF'}.get(int(v), str(int(v))))
    return Column(name, name, max(11, len(name)), _num('.4g'))


def available(dtype: np.dtype) -> list[str]:
    """Field names of a record dtype plus the derived ones it allows."""
    names = list(dtype.names or ())
    if {'vx', 'vy'} <= set(names):
        names += list(DERIVED)
    return names


def column_values(records: np.ndarray, name: str) -> np.ndarray:
    """A field of ``records`` or a derived value (``speed``, ``course`` in degrees)."""
    if name == 'speed':
        return np.hypot(records['vx'], records['vy'])
    if name == 'course':
        return np.degrees(np.arctan2(records['vy'], records['vx']))
    if name == 'bearing':
        return np.degrees(records['bearing'])
    return records[name]


def visible(records: np.ndarray, show_all: bool) -> np.ndarray:
    """The records to show: confirmed ones only (where there is a ``confirmed`` field) unless ``show_all``."""
    if show_all or 'confirmed' not in (records.dtype.names or ()):
        return records
    return records[records['confirmed'] != 0]


def _check(dtype: np.dtype, fields: list[str]) -> None:
    known = available(dtype)
    unknown = [f for f in fields if f not in known]
    if unknown:
        raise EchoError(f'no field(s) {unknown} in these records; available: {", ".join(known)}')


def table_columns(dtype: np.dtype, fields: list[str] | None = None, show_all: bool = False,
                  width: int = WIDTH) -> tuple[list[Column], list[str]]:
    """The table's columns for records of ``dtype`` and the fields left out to fit ``width`` characters.

    Without ``fields``: id, x, y, then speed, course, existence and fusion for clouds with a
    velocity, else range, bearing, amplitude and clutter density where present; ``confirmed``
    with ``show_all``.
    """
    names = list(dtype.names or ())
    if fields:
        _check(dtype, fields)
        wanted = list(fields)
    else:
        ident = [n for n in names if n in _ID_FIELDS][:1]
        if {'vx', 'vy'} <= set(names):
            rest = ['speed', 'course', 'existence', 'fusion']
        else:
            rest = ['range', 'bearing', 'amplitude', 'clutter_density']
        wanted = [n for n in ident + ['x', 'y'] + rest if n in available(dtype)]
        if show_all and 'confirmed' in names:
            wanted.append('confirmed')
        if not wanted:
            wanted = names
    columns, used = [], 0
    for i, name in enumerate(wanted):
        col = _column(name)
        if used + col.width + (1 if columns else 0) > width:
            return columns, wanted[i:]
        used += col.width + (1 if columns else 0)
        columns.append(col)
    return columns, []


def stamp_text(stamp_ns: int) -> str:
    """Seconds of a stamp in nanoseconds, written exactly (``12.000000001``)."""
    sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
    return f'{sec}.{nsec:09d}'


def format_table(records: np.ndarray, columns: list[Column], *, title: str = '', max_rows: int = 40,
                 show_all: bool = False, dropped: list[str] = ()) -> list[str]:
    """Lines of a table of ``records`` (already decoded; filtered here with :func:`visible`).

    Rows are sorted by id (confirmed first with ``show_all``); at most ``max_rows`` are shown,
    then a line says how many more there are.
    """
    shown = visible(records, show_all)
    names = records.dtype.names or ()
    ident = next((n for n in _ID_FIELDS if n in names), None)
    if ident is not None and len(shown):
        keys = [shown[ident]] + ([shown['confirmed'] == 0] if 'confirmed' in names else [])
        shown = shown[np.lexsort(keys)]
    what = (f'{len(shown)} confirmed of {len(records)} records' if 'confirmed' in names and not show_all
            else f'{len(records)} records')
    lines = [f'{title}  {what}'.strip()]
    if dropped:
        note = f'(not shown, to fit {WIDTH} columns: {", ".join(dropped)})'
        if len(note) > WIDTH:
            note = f'(not shown, to fit {WIDTH} columns: {len(dropped)} fields, {dropped[0]} ... {dropped[-1]})'
        lines.append(note)
    lines.append(' '.join(c.title.rjust(c.width) for c in columns))
    values = [column_values(shown, c.name) for c in columns]
    for i in range(min(len(shown), max_rows)):
        lines.append(' '.join(c.text(v[i]).rjust(c.width) for c, v in zip(columns, values)))
    if len(shown) > max_rows:
        lines.append(f'... {len(shown) - max_rows} more (--rows)')
    return lines


def record_fields(dtype: np.dtype, fields: list[str] | None = None) -> list[str]:
    """The fields CSV and JSON write: ``fields`` (checked) or every field of the record."""
    if fields:
        _check(dtype, fields)
        return list(fields)
    return list(dtype.names or ())


def _plain(value) -> object:
    """A Python int or float (the float's repr round-trips), lists for sub-array fields."""
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value]
    if isinstance(value, (np.integer, int)):
        return int(value)
    return float(value)


def csv_header(names: list[str]) -> list[str]:
    """The CSV header row: ``stamp`` then the field names."""
    return ['stamp', *names]


def csv_rows(records: np.ndarray, names: list[str], stamp_ns: int) -> list[list[str]]:
    """One CSV row per record: the exact stamp, then each value as ``repr`` (ints as ints)."""
    stamp = stamp_text(stamp_ns)
    cols = [column_values(records, n) for n in names]
    return [[stamp, *(repr(_plain(c[i])) for c in cols)] for i in range(len(records))]


def json_line(records: np.ndarray, names: list[str], stamp_ns: int, frame_id: str) -> str:
    """One JSON object for a message: ``stamp`` [s], ``frame_id``, ``records`` (non-finite as null)."""
    def clean(v):
        if isinstance(v, list):
            return [clean(x) for x in v]
        return v if not isinstance(v, float) or math.isfinite(v) else None
    cols = [column_values(records, n) for n in names]
    recs = [{n: clean(_plain(c[i])) for n, c in zip(names, cols)} for i in range(len(records))]
    return json.dumps({'stamp': stamp_ns / 1e9, 'frame_id': frame_id, 'records': recs})


class Printer:
    """Writes decoded messages in the chosen format; counts them."""

    def __init__(self, args: argparse.Namespace, topic: str, out=sys.stdout) -> None:
        self.args, self.topic, self.out = args, topic, out
        self.fields = [f for f in args.fields.split(',') if f] if args.fields else None
        self.count = 0
        self.writer = csv.writer(out, lineterminator='\n') if args.csv else None
        self.names: list[str] | None = None
        self.redraw = not args.scroll and not args.csv and not args.json and out.isatty()

    def __call__(self, msg) -> None:
        import sonar_tracking.msgs as ma
        try:
            records = ma.cloud_to_array(msg)
            stamp = ma.header_ns(msg)
        except ma.AdapterError as exc:
            print(f'sonar_echo: message dropped: {exc}', file=sys.stderr)
            return
        records = records.reshape(-1)
        a = self.args
        if a.csv or a.json:
            if self.names is None:
                self.names = record_fields(records.dtype, self.fields)
                if a.csv:
                    self.writer.writerow(csv_header(self.names))
            shown = visible(records, a.all)
            missing = [n for n in self.names if n not in available(records.dtype)]
            if missing:
                print(f'sonar_echo: message dropped: it has no field(s) {missing}', file=sys.stderr)
                return
            if a.csv:
                self.writer.writerows(csv_rows(shown, self.names, stamp))
            else:
                self.out.write(json_line(shown, self.names, stamp, msg.header.frame_id) + '\n')
        else:
            columns, dropped = table_columns(records.dtype, self.fields, a.all)
            title = f'{self.topic}  stamp {stamp_text(stamp)}  frame {msg.header.frame_id or "-"}'
            lines = format_table(records, columns, title=title, max_rows=a.rows, show_all=a.all, dropped=dropped)
            self.out.write(('\x1b[H\x1b[2J' if self.redraw else '' if self.count == 0 else '\n')
                           + '\n'.join(lines) + '\n')
        self.out.flush()
        self.count += 1


def _subscription_qos(node, topic: str, choice: str, depth: int = 10):
    """The QoS to subscribe with, or None while ``auto`` has no publisher to follow yet."""
    if choice != 'auto':
        from sonar_tracking.ros.qos import input_profile
        return input_profile(choice, depth)
    infos = node.get_publishers_info_by_topic(topic)
    if not infos:
        return None
    wrong = {i.topic_type for i in infos} - {CLOUD_TYPE}
    if wrong:
        raise EchoError(f'{topic} carries {", ".join(sorted(wrong))}, not {CLOUD_TYPE}: not a record topic')
    from sonar_tracking.ros.qos import offered_profile, qos_from_rclpy
    return offered_profile([qos_from_rclpy(i.qos_profile) for i in infos], depth)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``sonar_echo``."""
    from rclpy.utilities import remove_ros_args
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(prog='sonar_echo', description=__doc__.split('\n\n')[0], allow_abbrev=False,
                                     epilog='ROS arguments follow --ros-args, e.g. --ros-args -r __ns:=/auv1')
    parser.add_argument('topic', help='record topic, e.g. tracks, gpf/tracks, detections, fls/regions, sonar/truth '
                                      '(relative names resolve in the node namespace)')
    form = parser.add_mutually_exclusive_group()
    form.add_argument('--csv', action='store_true', help='CSV: a header, then one row per record')
    form.add_argument('--json', action='store_true', help='JSON lines: one object per message')
    parser.add_argument('--all', action='store_true', help='show tentative (unconfirmed) records too')
    parser.add_argument('--once', action='store_true', help='print one message and exit')
    parser.add_argument('--count', type=int, default=0, metavar='N', help='exit after N messages')
    parser.add_argument('--fields', default='', metavar='A,B,...',
                        help='fields to print (derived: speed, course); default: a table that fits 100 columns, '
                             'every field in CSV/JSON')
    parser.add_argument('--rows', type=int, default=40, metavar='N', help='table rows per message (default 40)')
    parser.add_argument('--scroll', action='store_true', help='print tables one below the other, never redraw')
    parser.add_argument('--qos', choices=('auto', 'reliable', 'sensor_data'), default='auto',
                        help="auto (default): the publishers' reliability and durability; sensor_data = best effort")
    parser.add_argument('--timeout', type=float, default=0.0, metavar='S',
                        help='exit with status 1 if fewer messages than asked arrived within S seconds (0 = wait)')
    args = parser.parse_args(remove_ros_args(['sonar_echo', *argv])[1:])
    if args.count < 0 or args.rows < 1:
        parser.error('--count must be >= 0 and --rows >= 1')
    wanted = 1 if args.once else args.count

    from sonar_tracking.ros.runtime import prepare_process
    prepare_process()
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import PointCloud2
    rclpy.init(args=['sonar_echo', *argv], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(f'sonar_echo_{os.getpid()}')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stopped = []
    signal.signal(signal.SIGINT, lambda *a: stopped.append(True))
    signal.signal(signal.SIGTERM, lambda *a: stopped.append(True))
    topic = node.resolve_topic_name(args.topic)
    printer = Printer(args, topic)
    status, t0, announced, subscription = 0, time.monotonic(), False, None
    try:
        while not stopped and not (wanted and printer.count >= wanted):
            if subscription is None:
                qos = _subscription_qos(node, topic, args.qos)
                if qos is not None:
                    subscription = node.create_subscription(PointCloud2, topic, printer, qos)
                elif not announced and time.monotonic() - t0 > 2.0:
                    print(f'sonar_echo: waiting for a publisher on {topic}', file=sys.stderr)
                    announced = True
            if args.timeout and time.monotonic() - t0 > args.timeout:
                print(f'sonar_echo: {printer.count} message(s) on {topic} within {args.timeout:g} s', file=sys.stderr)
                status = 1
                break
            executor.spin_once(timeout_sec=0.1)
    except EchoError as exc:
        print(f'sonar_echo: error: {exc}', file=sys.stderr)
        status = 2
    except BrokenPipeError:
        # The reader went away (``| head``): stop quietly, and keep Python from reporting it at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except ExternalShutdownException:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return status


if __name__ == '__main__':
    sys.exit(main())
