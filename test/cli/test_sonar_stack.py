"""sonar_stack: children with prefixed logs, exit policies, clean stop, no orphans."""
from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sonar_tracking import process
from sonar_tracking.cli.sonar_stack import StackError, command, load_stack, move

pytestmark = pytest.mark.ros


def write(tmp_path, text):
    p = tmp_path / 'stack.yaml'
    p.write_text(text)
    return p


def start(path, *args):
    return subprocess.Popen([sys.executable, '-m', 'sonar_tracking.cli.sonar_stack', '--config', str(path), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
                            preexec_fn=process.child_dies_with_parent())


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie is dead too.
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().split()[2] != 'Z'
    except FileNotFoundError:
        return False


def pids(out):
    return {m.group(1): int(m.group(2)) for m in re.finditer(r'started (\S+) \(pid (\d+)\)', out)}


def read_until(proc, pattern, timeout=30.0):
    """Read the stack's output until a line matches; returns everything read."""
    text, deadline = '', time.monotonic() + timeout
    os.set_blocking(proc.stdout.fileno(), False)
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line:
            text += line
            if re.search(pattern, text):
                return text
        else:
            time.sleep(0.05)
    raise AssertionError(f'no {pattern!r} in:\n{text}')


def test_runs_until_the_simulator_finishes_with_prefixed_logs(tmp_path):
    path = write(tmp_path, '''
nodes:
  seaking_sim:
    parameters: {scenario: scenario1, rate: 4.0, duration: 3.0, shutdown_when_done: true}
  active_detector:
    params_file: package:active_detector.yaml
    parameters: {esc.enabled: false}
''')
    proc = start(path)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 0, out
    assert re.search(r'^\[seaking_sim\] .*finished after 3 sectors', out, re.M)
    assert re.search(r'^\[active_detector\] .*ESC off', out, re.M)
    assert 'seaking_sim exited with status 0: stopping the stack' in out
    for name, pid in pids(out).items():
        assert not alive(pid), name


def test_the_imaging_stack_detects_by_cfar_in_every_frame():
    """The shipped imaging stack as shipped: the Oculus preset's CA-CFAR detector and the tracker
    take every frame of the simulated imaging sonar (none lost before it was read)."""
    from sonar_tracking.cli.sonar_stack import find_stack
    proc = start(find_stack('imaging'), '--set', 'seaking_sim.duration=0.5')
    out, _ = proc.communicate(timeout=120)
    assert proc.returncode == 0, out
    assert re.search(r'^\[seaking_sim\] .*finished after 10 sectors', out, re.M), out
    assert re.search(r'^\[active_detector\] .*CA-CFAR \(P_fa 1e-05 per cell, 134 training cells\)', out, re.M), out
    assert 'lost before they were read' not in out, out


def test_sigterm_stops_every_child_within_five_seconds(tmp_path):
    path = write(tmp_path, '''
nodes:
  seaking_sim: {parameters: {scenario: fls3, rate: 1.0}}
  active_detector: {}
''')
    proc = start(path)
    out = read_until(proc, r'\[active_detector\].*threshold')
    t0 = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    rest, _ = proc.communicate(timeout=10)
    assert time.monotonic() - t0 < 5.0
    assert proc.returncode == 0
    for name, pid in pids(out + rest).items():
        assert not alive(pid), name


def test_a_dead_child_is_restarted_or_stops_the_stack(tmp_path):
    path = write(tmp_path, '''
max_restarts: 1
nodes:
  seaking_sim: {parameters: {scenario: fls3, rate: 1.0}, on_exit: restart}
  active_detector: {on_exit: stop}
''')
    proc = start(path)
    out = read_until(proc, r'\[active_detector\].*threshold')
    first = pids(out)
    os.killpg(first['seaking_sim'], signal.SIGKILL)
    out += read_until(proc, r'restarting \(1/1\)')
    os.killpg(first['active_detector'], signal.SIGKILL)
    rest, _ = proc.communicate(timeout=20)
    assert 'active_detector exited with status -9: stopping the stack' in rest
    assert proc.returncode == 1


def test_a_killed_stack_leaves_no_orphans(tmp_path):
    path = write(tmp_path, '''
nodes:
  seaking_sim: {parameters: {scenario: fls3, rate: 1.0}}
''')
    proc = start(path)
    out = read_until(proc, r'\[seaking_sim\].*SeaKing')
    child = pids(out)['seaking_sim']
    os.killpg(proc.pid, signal.SIGKILL)   # the stack only: its child is in a session of its own
    proc.wait()
    deadline = time.monotonic() + 10
    while alive(child) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(child)


@pytest.mark.parametrize('text, match', [
    ('nodes: {}', 'at least one node'),
    ('nodes: {x: {executable: no_such_node}}', 'unknown executable'),
    ('nodes: {seaking_sim: {on_exit: explode}}', 'on_exit must be one of'),
    ('nodes: {seaking_sim: {params_file: nowhere.yaml}}', 'not found'),
    ('nodes: {seaking_sim: {paramters: {}}}', 'unknown keys'),
])
def test_bad_stack_files_are_refused(tmp_path, text, match):
    with pytest.raises(StackError, match=match):
        load_stack(write(tmp_path, text))


def test_command_line_of_a_child(tmp_path):
    cfg = load_stack(write(tmp_path, '''
nodes:
  active_detector:
    params_file: package:active_detector.yaml
    parameters: {esc.density_source: best_track, sonar_pose: [1.0, 2.0, 0.0]}
    remappings: {/detections: /harbour/detections}
'''))
    cmd = command(cfg.nodes[0])
    assert cmd[1:3] == ['-m', 'sonar_tracking.nodes.active_detector']
    assert cmd[cmd.index('--params-file') + 1].endswith('config/active_detector.yaml')
    assert '-p' in cmd and 'esc.density_source:="best_track"' in cmd and 'sonar_pose:=[1.0, 2.0, 0.0]' in cmd
    assert '/detections:=/harbour/detections' in cmd


# --- names, settings, namespaces -----------------------------------------------------------------


def test_stacks_are_found_by_name_in_the_package_config(tmp_path, monkeypatch):
    from sonar_tracking.cli.sonar_stack import find_stack, shipped_stacks
    monkeypatch.chdir(tmp_path)   # outside the source tree
    harbour = find_stack('harbour')
    assert harbour.name == 'stack_harbour.yaml' and harbour.is_file()
    assert find_stack('stack_fls.yaml').name == 'stack_fls.yaml' and find_stack('fls') == find_stack('stack_fls')
    assert {'stack_harbour.yaml', 'stack_fls.yaml'} <= {p.name for p in shipped_stacks()}
    own = write(tmp_path, 'nodes: {seaking_sim: {}}')
    assert find_stack(str(own)) == own
    with pytest.raises(StackError, match='shipped stacks: .*stack_harbour.yaml'):
        find_stack('nowhere')


def test_a_stack_name_is_looked_up_in_the_installed_share(tmp_path, monkeypatch):
    import sonar_tracking.resources as resources
    from sonar_tracking.cli.sonar_stack import find_stack, shipped_stacks
    share = tmp_path / 'install' / 'share' / 'sonar_tracking' / 'config'
    share.mkdir(parents=True)
    (share / 'stack_tank.yaml').write_text('nodes: {seaking_sim: {}}')
    monkeypatch.setattr(resources, 'config_dirs', lambda: [tmp_path / 'src' / 'config', share])
    monkeypatch.chdir(tmp_path)
    assert find_stack('tank') == share / 'stack_tank.yaml' == find_stack('stack_tank.yaml')
    assert shipped_stacks() == [share / 'stack_tank.yaml']


def test_installed_sonar_stack_finds_a_stack_by_name_outside_the_source_tree(tmp_path):
    install = Path(os.environ.get('SONAR_TRACKING_INSTALL', Path(__file__).resolve().parents[2] / 'install'))
    if not (install / 'setup.bash').exists():
        pytest.fail(f'{install} has no colcon install; run `make build` (make test does it)')
    env = {k: v for k, v in os.environ.items() if k != 'SONAR_TRACKING_CONFIG'}
    exe = install / 'sonar_tracking' / 'lib' / 'sonar_tracking' / 'sonar_stack'
    r = subprocess.run(['bash', '-c', f'source {install}/setup.bash && exec {exe} harbour --dry-run '
                        '--namespace /auv1 --set seaking_sim.duration=30'],
                       capture_output=True, text=True, timeout=60, cwd=tmp_path, env=env)
    assert r.returncode == 0, r.stderr
    first = r.stdout.splitlines()[0]
    # colcon --symlink-install finds the source tree's config first, a plain install its share/.
    assert first.startswith('# ') and first.endswith('/config/stack_harbour.yaml in /auv1')
    sim = next(line for line in r.stdout.splitlines() if 'sonar_tracking.nodes.seaking_sim' in line)
    assert '-r __ns:=/auv1' in sim and 'duration:=30' in sim


def test_settings_override_parameters_with_yaml_types(tmp_path):
    from sonar_tracking.cli.sonar_stack import apply_settings
    cfg = load_stack(write(tmp_path, '''
nodes:
  seaking_sim: {parameters: {rate: 1.0, scenario: fls3}}
  active_detector: {}
'''))
    apply_settings(cfg, ['seaking_sim.rate=0', 'seaking_sim.scenario=scenario1', 'active_detector.esc.enabled=false',
                         'active_detector.esc.desired_clutter_density=1e-5', 'active_detector.sonar_pose=[1, 2.5, 0]'])
    sim, det = cfg.nodes
    assert sim.parameters == {'rate': 0, 'scenario': 'scenario1'}
    assert det.parameters == {'esc.enabled': False, 'esc.desired_clutter_density': 1e-5, 'sonar_pose': [1, 2.5, 0]}
    cmd = command(det)
    assert 'esc.enabled:=false' in cmd and 'esc.desired_clutter_density:=1e-05' in cmd
    for bad, match in [('seaking_sim.rate', 'NODE.PARAM=VALUE'), ('rate=1', 'NODE.PARAM=VALUE'),
                       ('tracker.rate=1', "no node 'tracker'.*seaking_sim, active_detector"),
                       ('seaking_sim.rate=[1', 'not YAML')]:
        with pytest.raises(StackError, match=match):
            apply_settings(cfg, [bad])


def test_namespaces_of_the_file_the_node_and_the_command_line(tmp_path):
    from sonar_tracking.cli.sonar_stack import move, resolve_name
    cfg = load_stack(write(tmp_path, '''
namespace: harbour
nodes:
  seaking_sim: {}
  active_detector: {namespace: left}
  imm_ipda_tracker: {namespace: /fixed}
'''))
    assert cfg.namespace == '/harbour'
    assert [n.namespace for n in cfg.nodes] == ['/harbour', '/harbour/left', '/fixed']
    move(cfg, 'auv1')
    assert cfg.namespace == '/auv1/harbour'
    assert [n.namespace for n in cfg.nodes] == ['/auv1/harbour', '/auv1/harbour/left', '/auv1/fixed']
    assert '__ns:=/auv1/harbour/left' in command(cfg.nodes[1])
    assert resolve_name('sonar/sector', '/auv1/harbour') == '/auv1/harbour/sonar/sector'
    assert resolve_name('/clock', '/auv1') == '/clock' and resolve_name('tracks', '/') == '/tracks'
    for bad in ('a//b', '1st', 'a-b', 'a/b c'):
        with pytest.raises(StackError, match='not a ROS namespace'):
            move(cfg, bad)
    with pytest.raises(StackError, match='not a ROS namespace'):
        load_stack(write(tmp_path, 'nodes: {seaking_sim: {namespace: "x y"}}'))
    with pytest.raises(StackError, match=r"unknown keys \['namespaces'\]"):
        load_stack(write(tmp_path, 'namespaces: a\nnodes: {seaking_sim: {}}'))


def test_a_namespaced_node_reads_the_parameter_file_as_it_is(tmp_path):
    """The package's files key sections /**/NODE, so a namespaced node is handed the file itself."""
    from sonar_tracking.cli.sonar_stack import check_params_files
    from sonar_tracking.resources import config_path
    cfg = load_stack(write(tmp_path, 'nodes: {seaking_sim: {params_file: package:sim_harbour.yaml, namespace: a}}'))
    check_params_files(cfg)
    cmd = command(cfg.nodes[0])
    assert cmd[cmd.index('--params-file') + 1] == str(config_path('sim_harbour.yaml'))


@pytest.mark.parametrize('key', ['seaking_sim', '/seaking_sim', '"/seaking_sim"'])
def test_a_section_keyed_for_the_root_namespace_only_is_refused_for_a_namespaced_node(tmp_path, key):
    from sonar_tracking.cli.sonar_stack import check_params_files
    (tmp_path / 'p.yaml').write_text(f'{key}:\n  ros__parameters:\n    seed: 3\n')
    root = load_stack(write(tmp_path, 'nodes: {seaking_sim: {params_file: p.yaml}}'))
    check_params_files(root)   # in the root namespace the section applies
    for ns in ('a', None):
        cfg = load_stack(write(tmp_path, 'nodes: {seaking_sim: {params_file: p.yaml' +
                               (f', namespace: {ns}' if ns else '') + '}}'))
        if ns is None:
            move(cfg, '/auv1')
        with pytest.raises(StackError, match=r'root namespace only.*/\*\*/seaking_sim'):
            check_params_files(cfg)
    (tmp_path / 'p.yaml').write_text('/**/seaking_sim:\n  ros__parameters:\n    seed: 3\n')
    check_params_files(cfg)


def test_a_relative_parameter_file_missing_beside_the_stack_is_an_error_not_the_package_file(tmp_path, capsys):
    """A copied stack without its preset must not run the package's preset silently; ``package:NAME``
    asks for it, a file beside the stack is used, and --dry-run shows which file each node reads."""
    from sonar_tracking.cli.sonar_stack import main
    from sonar_tracking.resources import config_path
    stack = write(tmp_path, 'nodes: {imm_ipda_tracker: {params_file: imm_ipda.yaml}}')
    with pytest.raises(StackError, match=r'imm_ipda.yaml not found.*package:imm_ipda.yaml'):
        load_stack(stack)
    assert main(['--config', str(stack), '--dry-run']) == 2
    assert 'package:imm_ipda.yaml' in capsys.readouterr().err
    package = load_stack(write(tmp_path, 'nodes: {imm_ipda_tracker: {params_file: package:imm_ipda.yaml}}'))
    assert package.nodes[0].params_file == config_path('imm_ipda.yaml')
    (tmp_path / 'imm_ipda.yaml').write_text('/**/imm_ipda_tracker:\n  ros__parameters:\n'
                                            '    detection.probability: 0.7\n')
    beside = load_stack(write(tmp_path, 'nodes: {imm_ipda_tracker: {params_file: imm_ipda.yaml}}'))
    assert beside.nodes[0].params_file == tmp_path / 'imm_ipda.yaml'
    assert main(['--config', str(tmp_path / 'stack.yaml'), '--dry-run']) == 0
    assert f'--params-file {tmp_path / "imm_ipda.yaml"}' in capsys.readouterr().out
    with pytest.raises(StackError, match='package config has no nowhere.yaml'):
        load_stack(write(tmp_path, 'nodes: {imm_ipda_tracker: {params_file: package:nowhere.yaml}}'))


def test_ros_args_namespace_is_the_stack_namespace(capsys):
    """``sonar_stack harbour --ros-args -r __ns:=/auv1``, the ``ros2 run`` habit, is ``--namespace /auv1``."""
    from sonar_tracking.cli.sonar_stack import main
    assert main(['harbour', '--dry-run', '--ros-args', '-r', '__ns:=/auv1']) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if not line.startswith('#')]
    assert len(lines) == 3 and all('__ns:=/auv1' in line for line in lines), lines
    assert main(['harbour', '--dry-run', '--namespace', '/auv1', '--ros-args', '--remap', '__ns:=/auv1/']) == 0
    capsys.readouterr()
    for bad, match in ((['--ros-args', '-p', 'seed:=3'], 'only -r __ns:=NS'),
                       (['--ros-args', '-r', 'tracks:=t'], 'only -r __ns:=NS'),
                       (['--namespace', '/a', '--ros-args', '-r', '__ns:=/b'], 'two namespaces')):
        with pytest.raises(SystemExit) as exc:
            main(['harbour', '--dry-run', *bad])
        assert exc.value.code == 2 and match in capsys.readouterr().err


def values(parameter_values) -> list:
    """Python values of rcl_interfaces/ParameterValue messages (bool, int, double, string)."""
    fields = {1: 'bool_value', 2: 'integer_value', 3: 'double_value', 4: 'string_value'}
    return [getattr(v, fields[v.type]) for v in parameter_values]


def test_two_harbour_stacks_in_namespaces_track_their_own_targets_without_cross_talk(ros):
    """``sonar_stack harbour --namespace /a`` and ``/b`` at once, 30 scans each: scenario 1 (course
    45 deg) in /a, scenario 2 (course 0 deg, turning left from 20 s) in /b; each confirmed track lies
    on its own pipeline's target, some 250 m from the other's. The simulators wait for one more listener
    than the stack (``wait_for_subscribers=2``): the test's, which subscribes once the graph and the
    parameters have been checked, so those checks run before any scan."""
    from rcl_interfaces.srv import GetParameters
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image, LaserScan, PointCloud2

    import sonar_tracking.msgs as ma
    keep_all = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    node = ros.node
    got = {k: [] for k in ('/a/tracks', '/b/tracks', '/a/sonar/truth', '/b/sonar/truth')}
    subs = [node.create_subscription(PointCloud2, t, got[t].append, keep_all) for t in got]
    scenario = {'/a': 'scenario1', '/b': 'scenario2'}
    procs = {ns: subprocess.Popen(
        [sys.executable, '-m', 'sonar_tracking.cli.sonar_stack', 'harbour', '--namespace', ns,
         '--set', f'seaking_sim.scenario={s}', '--set', 'seaking_sim.duration=30',
         '--set', 'seaking_sim.wait_for_subscribers=2'],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
        preexec_fn=process.child_dies_with_parent())
        for ns, s in scenario.items()}
    try:
        def publishers(topic):
            return sorted((i.node_name, i.node_namespace) for i in node.get_publishers_info_by_topic(topic))

        def topics_of(name, ns):
            try:
                return ({t for t, _ in node.get_publisher_names_and_types_by_node(name, ns)}
                        | {t for t, _ in node.get_subscriber_names_and_types_by_node(name, ns)})
            except Exception:   # not discovered yet
                return set()

        global_names = {'/rosout', '/parameter_events', '/clock'}
        for ns in scenario:
            ros.wait(lambda ns=ns: publishers(f'{ns}/tracks') == [('imm_ipda_tracker', ns)], 60,
                     f'{ns}/tracks publisher')
            ros.wait(lambda ns=ns: publishers(f'{ns}/detections') == [('active_detector', ns)], 30, f'{ns}/detections')
            ros.wait(lambda ns=ns: publishers(f'{ns}/sonar/truth') == [('seaking_sim', ns)], 60, f'{ns}/sonar/truth')
            for name in ('seaking_sim', 'active_detector', 'imm_ipda_tracker'):
                ros.wait(lambda ns=ns, name=name: f'{ns}/tracks' in topics_of(name, ns)
                         or f'{ns}/sonar/sector' in topics_of(name, ns), 30, f'{ns}/{name} in the graph')
                # Every topic of the node is in its namespace (none in the root, none in the other's).
                names = topics_of(name, ns)
                assert all(t.startswith(f'{ns}/') or t in global_names for t in names), (name, ns, sorted(names))
            # The parameters through the CLI's protocol: --set, and the section of sim_harbour.yaml
            # (clutter_lambda 1.6; scenario 1's own default is 1.2), moved into the namespace.
            client = node.create_client(GetParameters, f'{ns}/seaking_sim/get_parameters')
            assert client.wait_for_service(timeout_sec=30)
            reply = ros.call(client, GetParameters.Request(names=['scenario', 'clutter_lambda', 'duration']))
            node.destroy_client(client)
            assert values(reply.values) == [scenario[ns], 1.6, 30.0]
        # Now let the simulators start.
        subs += [node.create_subscription(Image, f'{ns}/sonar/sector', lambda m: None, 10) for ns in scenario]
        subs += [node.create_subscription(LaserScan, f'{ns}/sonar/sector_info', lambda m: None, 10) for ns in scenario]
        outs = {ns: p.communicate(timeout=60)[0] for ns, p in procs.items()}
    finally:
        for p in procs.values():
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
                p.communicate()
        for s in subs:
            node.destroy_subscription(s)
    for ns, p in procs.items():
        assert p.returncode == 0, outs[ns]
        assert 'finished after 30 sectors' in outs[ns], outs[ns]
    truth = {ns: ma.cloud_to_array(got[f'{ns}/sonar/truth'][-1])[0] for ns in scenario}
    assert math.hypot(truth['/a']['x'] - truth['/b']['x'], truth['/a']['y'] - truth['/b']['y']) > 150
    for ns, other in (('/a', '/b'), ('/b', '/a')):
        last = ma.cloud_to_array(got[f'{ns}/tracks'][-1])
        assert len(got[f'{ns}/tracks']) >= 15 and len(last) >= 1 and all(last['confirmed'] == 1)
        own = np.hypot(last['x'] - truth[ns]['x'], last['y'] - truth[ns]['y'])
        cross = np.hypot(last['x'] - truth[other]['x'], last['y'] - truth[other]['y'])
        assert own.min() < 30.0 and cross.min() > 100.0, (ns, last[['track_id', 'x', 'y']], truth)


def test_namespaced_package_topics_are_left_out_of_the_recorder_wait():
    from sonar_tracking.cli.sonar_stack import _late_topics
    topics = ['/a/tracks', '/a/sonar/sector', '/a/fls/image_info', '/clock', '/tracks']
    assert _late_topics(topics, '/a') == ['/a/tracks', '/a/sonar/sector']
    assert _late_topics(topics, '/') == []


def test_preset_gives_every_node_reading_a_sensor_preset_another(tmp_path, capsys):
    from sonar_tracking.cli.sonar_stack import main, sensor_presets

    def children(*args):
        assert main([*args, '--dry-run']) == 0
        return [line for line in capsys.readouterr().out.splitlines() if not line.startswith('#')]
    aris = sensor_presets()['aris_didson']
    lines = children('recording', '--preset', 'aris_didson')
    assert len(lines) == 2 and all(f'--params-file {aris} ' in line + ' ' for line in lines), lines
    own = tmp_path / 'my_sonar.yaml'
    own.write_text(aris.read_text())
    lines = children('recording_active', '--preset', str(own))
    assert [line.split(' -m ')[1].split()[0] for line in lines] == ['sonar_tracking.nodes.imm_ipda_tracker',
                                                                    'sonar_tracking.nodes.active_detector']
    assert all(f'--params-file {own}' in line for line in lines), lines
    assert main(['recording', '--preset', 'sonar9000', '--dry-run']) == 2
    assert 'no such sensor preset; the package has aris_didson, gemini_720, micron_seaking' in capsys.readouterr().err
    assert main(['harbour', '--preset', 'ping360', '--dry-run']) == 2
    assert 'no node of this stack reads a sensor preset' in capsys.readouterr().err


def test_replay_is_the_last_child_and_waits_for_the_sector_readers(capsys):
    from sonar_tracking.cli.sonar_stack import main
    assert main(['recording_active', '--replay', 'rec_sectors --rate 2', '--dry-run']) == 0
    last = capsys.readouterr().out.splitlines()[-1]
    assert last.split(' -m ')[1] == ('sonar_tracking.cli.bag_replay rec_sectors --rate 2 --wait-for /sonar/sector '
                                     '/sonar/sector_info --ros-args')
    assert main(['recording_active', '--replay', 'rec_sectors', '--namespace', '/a', '--dry-run']) == 2
    assert 'run it in the root namespace' in capsys.readouterr().err


def test_the_nodes_with_a_status_are_the_processing_nodes():
    """The stack waits for the state of exactly the nodes that publish one, under their executables' names."""
    import importlib
    import inspect

    from sonar_tracking.cli.sonar_stack import STATUS_EXECUTABLES, _entry_points
    from sonar_tracking.ros import SonarNode
    found = set()
    for exe, module in _entry_points().items():
        if module.startswith('sonar_tracking.nodes.'):
            classes = [c for c in vars(importlib.import_module(module)).values()
                       if inspect.isclass(c) and issubclass(c, SonarNode) and c.__module__ == module]
            if classes:
                assert f"super().__init__('{exe}'" in inspect.getsource(classes[0]), exe
                found.add(exe)
    assert found == STATUS_EXECUTABLES


def test_a_stack_with_a_view_runs_its_simulator_in_real_time_unless_told_otherwise(capsys):
    """``--view``: a simulator the stack runs at full speed runs as the sensor would (rate 1), so that
    the page keeps up; a node's ``view_parameters`` apply under ``--view`` alone; a rate given with
    ``--set`` stays, and without ``--view`` the file's rate (full speed) stays."""
    from sonar_tracking.cli.sonar_stack import main

    def sim_line(*args: str, stack: str = 'harbour') -> str:
        assert main([stack, '--dry-run', *args]) == 0
        return next(line for line in capsys.readouterr().out.splitlines() if 'seaking_sim' in line
                    and not line.startswith('#'))
    assert 'rate:=1.0' in sim_line('--view')
    assert 'rate:=0.0' in sim_line()
    assert 'rate:=4' in sim_line('--view', '--set', 'seaking_sim.rate=4')
    assert 'rate:=0.2' in sim_line('--view', stack='imaging')    # the file's view_parameters
    assert 'rate:=0.5' in sim_line(stack='imaging')              # half real time: the frames cost CPU
    assert 'rate:=0.5' in sim_line('--view', '--set', 'seaking_sim.rate=0.5', stack='imaging')


def test_a_stack_files_view_args_come_before_the_views_own(tmp_path):
    from sonar_tracking.cli.sonar_stack import StackError, find_stack, load_stack, view_spec
    fls = load_stack(find_stack('fls'))
    assert view_spec(fls, '').extra_args == ['--always', '--qos', 'reliable', '--fan-period', '2']
    assert view_spec(fls, '--fan-period 1 --batch 0.5').extra_args[-4:] == ['--fan-period', '1', '--batch', '0.5']
    assert load_stack(find_stack('harbour')).view_args == []
    bad = tmp_path / 'bad.yaml'
    bad.write_text('view_args: {fan: 2}\nnodes: {seaking_sim: {}}\n')
    with pytest.raises(StackError, match='view_args'):
        load_stack(bad)
