"""``sonar_import``: turn a recording of a real sonar into a ROS 2 bag of the package's input contract.

Inputs: ROS 1 ``.bag`` and ROS 2 bags of scanning sonars (Tritech Micron/SeaKing scan lines,
Ping360 echoes) or of ``marine_acoustic_msgs/ProjectedSonarImage`` (Oculus, Gemini, BlueView,
DAVE), Ping Viewer ``.bin`` logs of the Ping360, and folders of frames (polar, or Cartesian fan
pictures) with a ``sonar.yaml``. Output: ``/sonar/sector`` + ``/sonar/sector_info`` (+
``/platform/odometry`` when the recording has odometry), MCAP by default. ``--inspect`` lists what
is recognised, the conventions applied with the source of each, and what would be written.

Conventions (head direction, head zero, angle unit, intensity coding) come from an option, else
the ``--preset``, else the sensor the recording names (its message type or format: see
:mod:`sonar_tracking.io.importers.conventions`), else the defaults.

``--picture RUN -o run.png`` draws a run recorded by ``sonar_stack --record`` (last FLS image,
regions, tracks, detections, sonar path).

Exit codes: 0 = everything imported; 1 = imported, but with problems (each printed with its topic
and stamp: undecodable or malformed messages skipped, pings padded, missing pings, time gaps, a
cut-off file, topics of unknown type, NaN values); 2 = nothing imported (bad arguments, unreadable
recording, a bad ``sonar.yaml``, angle table, stamps file or fan geometry, a folder of frames
without ``sonar.yaml``, no sonar topic, no usable sector, output exists). The bag is built in a
hidden folder beside the output and renamed to it only when the import succeeded: exit code 2
leaves no output.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

__all__ = ['main', 'load_preset']

EXIT_OK, EXIT_PROBLEMS, EXIT_FAILED = 0, 1, 2


def load_preset(name: str) -> dict:
    """The importer settings of a sensor preset (``config/sensors/NAME.yaml``, section ``/**/sonar_import:
    ros__parameters:``, so the file is also a valid ROS parameter file for the nodes it configures)."""
    from sonar_tracking.io.importers.conventions import load_preset as load
    return load(name)


def _stamp(ns: int) -> str:
    return f'{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}' if ns else '-'


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='sonar_import', description=__doc__.split('\n\n')[0],
                                epilog='Exit codes: 0 all imported, 1 imported with problems, 2 nothing imported.')
    p.add_argument('recording', type=Path, help='.bag, ROS 2 bag (directory/.mcap/.db3), Ping Viewer .bin, or a '
                   'folder of frames (polar or fan pictures) with sonar.yaml')
    p.add_argument('-o', '--output', type=Path, help='bag directory to create (never overwritten)')
    p.add_argument('--inspect', action='store_true', help='list the recognised topics, the conventions applied and '
                   'where each comes from, and what the import would write; write nothing')
    p.add_argument('--picture', action='store_true', help='draw the run recorded in RECORDING (sonar_stack --record: '
                   'last FLS image, regions, tracks, detections, sonar path) into the PNG given by -o')
    p.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    p.add_argument('--preset', help='sensor preset (config/sensors/NAME.yaml or a path): importer settings; '
                   'options given here override it')
    p.add_argument('--topic', help='sonar topic in the source bag (default: the one recognised)')
    p.add_argument('--odometry-topic', help='nav_msgs/Odometry topic (default: the only one; "none" = skip), or a '
                   'PoseStamped / PoseWithCovarianceStamped topic to use as the platform pose')
    p.add_argument('--pings', type=int, help='pings per sector (default 0 = one sector per sweep)')
    p.add_argument('--max-gap', type=float, help='seconds between pings that end a sweep (default 2)')
    head = p.add_mutually_exclusive_group()
    head.add_argument('--clockwise', dest='head_clockwise', action='store_const', const=True,
                      help='head angles / beam azimuths grow clockwise seen from above')
    head.add_argument('--counter-clockwise', dest='head_clockwise', action='store_const', const=False,
                      help='they grow counter-clockwise (REP-103; the default unless the message type names '
                      'a sensor)')
    p.add_argument('--head-zero', type=float, dest='head_zero_deg', help='head angle [deg] that points forward')
    p.add_argument('--angle-unit', choices=('auto', 'rad', 'deg', 'grad'), help='unit of head angles in messages')
    p.add_argument('--beam-frame', choices=('auto', 'message', 'rep103'), help='ProjectedSonarImage beam frame')
    p.add_argument('--image-layout', choices=('range_major', 'beam_major'), help='ProjectedSonarImage data order')
    p.add_argument('--speed-of-sound', type=float, help='m/s, for pings with a sample period (default 1500)')
    p.add_argument('--intensity', choices=('keep', 'linear', 'linear_amplitude', 'linear_power', 'db', 'display'),
                   help='keep the recorded values (default) or decode them to linear amplitude with this coding '
                   '(linear = linear_amplitude)')
    p.add_argument('--db-span', type=float, help='db coding: dB spanned by the full count range (default 60)')
    p.add_argument('--gamma', type=float, help='display coding: amplitude = (value / full scale)^gamma')
    p.add_argument('--noise-floor', type=float, help='decoded amplitudes at or below this become 0')
    p.add_argument('--blank-range', type=float, help='m: range bins nearer than this become 0 (ringdown)')
    p.add_argument('--max-range', type=float, help='m: range bins beyond this are cut (0 = keep all)')
    p.add_argument('--frame-id', help='frame_id of the sectors (default: the recording\'s)')
    p.add_argument('--date', default='', help='Ping Viewer logs: date of the recording, YYYY-MM-DD')
    return p


_FLAT = {'topic': 'topic', 'odometry_topic': 'odometry_topic', 'pings': 'pings', 'max_gap': 'max_gap',
         'head_clockwise': 'head_clockwise', 'head_zero_deg': 'head_zero_deg', 'angle_unit': 'angle_unit',
         'beam_frame': 'beam_frame', 'image_layout': 'image_layout', 'speed_of_sound': 'speed_of_sound',
         'frame_id': 'frame_id', 'db_span': 'intensity.db_span', 'gamma': 'intensity.gamma',
         'noise_floor': 'intensity.noise_floor', 'blank_range': 'intensity.blank_range',
         'max_range': 'intensity.max_range'}


def given_settings(args: argparse.Namespace) -> dict[str, tuple[Any, str]]:
    """The settings given by a preset (if any) overridden by the command line: ``{flat name: (value,
    source)}``, the source naming the option or the preset."""
    given: dict[str, tuple[Any, str]] = {}
    if args.preset:
        given = {name: (value, f'preset {args.preset}') for name, value in load_preset(args.preset).items()}
    for attr, name in _FLAT.items():
        value = getattr(args, attr)
        if value is not None:
            flag = {'head_clockwise': '--clockwise' if value else '--counter-clockwise',
                    'head_zero_deg': '--head-zero'}.get(attr, '--' + attr.replace('_', '-'))
            given[name] = (value, f'option {flag}')
    if args.intensity is not None:
        given['decode'] = (args.intensity != 'keep', 'option --intensity')
        if args.intensity != 'keep':
            coding = 'linear_amplitude' if args.intensity == 'linear' else args.intensity
            given['intensity.coding'] = (coding, 'option --intensity')
    return given


def options_from_args(args: argparse.Namespace):
    """ImportOptions from a preset (if any) overridden by the command line (no conventions of the
    recording's sensor: those come with :func:`sonar_tracking.io.importers.conventions.resolve`)."""
    from sonar_tracking.io.importers import ImportOptions
    return ImportOptions.from_flat({name: value for name, (value, _) in given_settings(args).items()})


def _conventions(recording, options, sources: dict[str, str]) -> list[tuple[str, str, str]]:
    """(convention, value, source) rows of what the import applies."""
    unit = recording.angle_unit_used(options)
    rows = []
    if unit:
        rows.append(('head direction', 'clockwise (bearing = -(head - zero))' if options.head_clockwise else
                     'counter-clockwise (bearing = head - zero)', sources['head_clockwise']))
        rows.append(('head zero', f'{options.head_zero_deg:g} deg', sources['head_zero_deg']))
        rows.append(('angle unit', unit + (' (auto: by the message type or format, and the angles)'
                                           if options.angle_unit == 'auto' else ''), sources['angle_unit']))
    else:
        rows.append(('bearings', 'negated (recorded clockwise)' if options.head_clockwise else
                     'as recorded (counter-clockwise, REP-103)', sources['head_clockwise']))
    if options.decode:
        rows.append(('intensity', f'decoded from {options.intensity.coding} to linear amplitude (32FC1)',
                     sources['intensity.coding']))
    else:
        rows.append(('intensity', 'kept as recorded (the front end decodes it)',
                     sources['decode']))
    return rows


def _report(stats, recording) -> None:
    for topic, stamp, text in stats.problems:
        print(f'warning: {topic or recording.path.name} @ {_stamp(stamp)}: {text}', file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``sonar_import``."""
    args = _parser().parse_args(argv)
    from sonar_tracking.core.config import ConfigError
    from sonar_tracking.io.bags import BagWriteError
    from sonar_tracking.io.importers import RecordingError, SectorBagWriter, open_recording, run_import
    from sonar_tracking.io.importers.conventions import DEFAULT_SOURCE, resolve
    try:
        given = given_settings(args)
        options = options_from_args(args)   # every value checked before anything is read
    except (ConfigError, ValueError, FileNotFoundError, OSError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_FAILED
    if args.picture:
        if args.output is None or args.output.suffix != '.png':
            print('error: --picture needs -o FILE.png', file=sys.stderr)
            return EXIT_FAILED
        from sonar_tracking.cli.import_picture import draw_run
        try:
            drawn = draw_run(args.recording, args.output)
        except Exception as exc:  # noqa: BLE001 - any reader failure is reported the same way
            print(f'error: cannot draw {args.recording}: {exc}', file=sys.stderr)
            return EXIT_FAILED
        print(f'sonar_import: drew {drawn} into {args.output}', file=sys.stderr)
        return EXIT_OK
    if not args.inspect and args.output is None:
        print('error: give -o/--output BAG (or --inspect)', file=sys.stderr)
        return EXIT_FAILED
    if args.output is not None and args.output.exists() and not args.inspect:
        print(f'error: {args.output} exists already; sonar_import never overwrites', file=sys.stderr)
        return EXIT_FAILED
    try:
        recording = open_recording(args.recording, args.date)
        topics = recording.topics()
        sensor, named_by = recording.sensor(options)
        try:
            options, sources = resolve(given, sensor, named_by)
        except (ConfigError, ValueError, FileNotFoundError) as exc:
            raise RecordingError(f'the conventions of {sensor.name if sensor else "its sensor"} cannot be '
                                 f'applied ({exc}); give --preset') from exc
        for name, (_, source) in recording.own_conventions().items():
            sources[name] = source
        if not args.inspect:
            recording.check(options)
    except RecordingError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_FAILED
    except Exception as exc:  # noqa: BLE001 - a reader library's own failure on bytes it does not expect
        print(f'error: {args.recording} cannot be read ({type(exc).__name__}: {exc})', file=sys.stderr)
        return EXIT_FAILED
    if args.inspect:
        print(f'{args.recording}: {recording.kind} recording')
        for t in topics:
            what = {'scanline': 'scanning sonar scan lines -> sectors', 'echo': 'scanning sonar echoes -> sectors',
                    'projected': 'imaging sonar frames -> one sector each',
                    'odometry': 'odometry -> /platform/odometry',
                    'pose': 'pose -> /platform/odometry if named by --odometry-topic'}.get(t.role, t.note or 'not used')
            count = '?' if t.count < 0 else t.count
            print(f'  {t.name:30s} {t.msgtype:45s} {count!s:>7} msgs  {what}')
        for line in recording.describe():
            print(f'  {line}')
        print('conventions (an option beats the preset, the preset the sensor the recording names, that the '
              'default):')
        rows = _conventions(recording, options, sources)
        width = max(len(value) for _, value, _ in rows)
        for name, value, source in rows:
            print(f'  {name:15s} {value:{width}s}  from {source}')
    if sources['head_clockwise'] == DEFAULT_SOURCE and recording.angle_unit_used(options):
        print(f'note: {named_by or args.recording.name} names no sensor this importer knows (Tritech, Ping360): '
              f'head angles are taken to grow counter-clockwise from {options.head_zero_deg:g} deg ahead (the '
              'defaults); if the picture is mirrored or turned, give --preset or --clockwise / --head-zero '
              '(--inspect lists the conventions)', file=sys.stderr)
    for t in topics:
        if t.note:
            recording.problem(t.name, 0, t.note)
    writer, committed, failure = None, False, ''
    try:
        if not args.inspect:
            writer = SectorBagWriter(args.output, args.storage)
        stats = run_import(recording, options, writer)
        if writer is not None and stats.sectors:
            writer.commit()
            committed = True
    except RecordingError as exc:
        failure = str(exc)
    except (BagWriteError, OSError) as exc:
        failure = f'cannot write {args.output}: {exc}'
    except Exception as exc:  # noqa: BLE001 - a reader library's own failure on bytes it does not expect
        failure = f'reading {args.recording} failed ({type(exc).__name__}: {exc})'
    finally:
        if writer is not None and not committed:      # nothing half-written is left at the output
            writer.discard()
    if failure:
        print(f'error: {failure}; nothing written', file=sys.stderr)
        return EXIT_FAILED
    _report(stats, recording)
    verb = 'would write' if args.inspect else 'wrote' if stats.sectors else 'wrote nothing:'
    geoms = ', '.join(f'{n} x ({b} bins x {w} beams, {inc:g} deg)' for (b, w, inc), n in stats.geometries.items())
    print(f'sonar_import: {verb} {stats.sectors} sectors ({geoms or "none"}) from {stats.pings_in} pings / '
          f'{stats.frames_in} frames ({stats.pings_out} ping columns), {stats.odometry} odometry messages'
          f'{"" if args.inspect or not stats.sectors else f" to {args.output}"}; {len(stats.problems)} problems',
          file=sys.stdout if args.inspect else sys.stderr)
    if stats.sectors == 0:
        return EXIT_FAILED
    return EXIT_PROBLEMS if stats.problems else EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
