"""Parameters keep their declared type after every kind of set, through the services the CLI uses."""
from __future__ import annotations

import pytest

pytestmark = pytest.mark.ros

NODES = ['sonar_tracking.nodes.active_detector:ActiveDetectorNode', 'sonar_tracking.nodes.fls_features:FlsFeaturesNode',
         'sonar_tracking.nodes.imm_ipda_tracker:ImmIpdaTrackerNode', 'sonar_tracking.nodes.gpf_tracker:GpfTrackerNode',
         'sonar_tracking.nodes.seaking_sim:SeaKingSimNode']

TRIALS = [True, 7, 2.5, 'text', [1, 2, 3], [1.5, 2.5], ['a'], [True]]


def node_class(path):
    import importlib
    module, cls = path.split(':')
    return getattr(importlib.import_module(module), cls)


@pytest.mark.parametrize('path', NODES, ids=lambda p: p.split(':')[1])
def test_every_parameter_keeps_its_type_whatever_is_set(ros, inproc, path):
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
    from rclpy.parameter import Parameter
    node = inproc(node_class(path), **({'rate': 0.0, 'scenario': 'clutter', 'duration': 1.0}
                                       if path.endswith('SeaKingSimNode') else {}))
    name = node.get_name()
    setc = ros.node.create_client(SetParameters, f'/{name}/set_parameters')
    getc = ros.node.create_client(GetParameters, f'/{name}/get_parameters')
    descc = ros.node.create_client(DescribeParameters, f'/{name}/describe_parameters')
    try:
        for c in (setc, getc, descc):
            assert c.wait_for_service(timeout_sec=20.0)
        names = sorted(n for n in node._parameters if n != 'use_sim_time')
        declared = {d.name: d.type for d in ros.call(descc, DescribeParameters.Request(names=names)).descriptors}
        assert all(t != ParameterType.PARAMETER_NOT_SET for t in declared.values())
        for trial in TRIALS:
            # One request for all: the service sets each parameter alone (atomically), exactly as it
            # does for the one-parameter request of `ros2 param set`.
            reply = ros.call(setc, SetParameters.Request(
                parameters=[Parameter(n, value=trial).to_parameter_msg() for n in names]))
            assert len(reply.results) == len(names)
            got = ros.call(getc, GetParameters.Request(names=names)).values
            types = dict(zip(names, (v.type for v in got)))
            changed = {n: (declared[n], types[n]) for n in names if types[n] != declared[n]}
            assert not changed, f'after setting {trial!r}: {changed}'
    finally:
        for c in (setc, getc, descc):
            ros.node.destroy_client(c)


def test_integers_for_doubles_are_converted_and_read_only_is_in_the_descriptor(ros, inproc):
    from rcl_interfaces.srv import DescribeParameters
    from rclpy.parameter import Parameter

    from sonar_tracking.nodes.gpf_tracker import GpfTrackerNode
    node = inproc(GpfTrackerNode)
    assert node.set_parameters([Parameter('cues.features', value=[20, 17, 3])])[0].successful
    assert list(node.get_parameter('cues.features').value) == [20.0, 17.0, 3.0]
    assert node.config.cues.features == (20.0, 17.0, 3.0)
    assert node.set_parameters([Parameter('lost.max_time', value=25)])[0].successful
    assert node.get_parameter('lost.max_time').value == 25.0 and node.config.lost.max_time == 25.0
    descc = ros.node.create_client(DescribeParameters, '/gpf_tracker/describe_parameters')
    try:
        assert descc.wait_for_service(timeout_sec=20.0)
        d = ros.call(descc, DescribeParameters.Request(names=['seed', 'particles'])).descriptors
        assert d[0].read_only and 'start-up only' in d[0].additional_constraints and not d[1].read_only
    finally:
        ros.node.destroy_client(descc)


def test_a_refusal_names_the_setting_once(inproc):
    from rclpy.parameter import Parameter

    from sonar_tracking.nodes.active_detector import ActiveDetectorNode
    node = inproc(ActiveDetectorNode)
    r = node.set_parameters([Parameter('threshold.initial', value=50.0)])[0]
    assert not r.successful and r.reason.startswith('threshold.initial = 50') and 'threshold.threshold' not in r.reason
    assert node.get_parameter('threshold.initial').value == 3.0


@pytest.mark.parametrize('node_path, name, value, other', [
    ('sonar_tracking.nodes.active_detector:ActiveDetectorNode', 'threshold.minimum', 5.0, 'threshold.initial'),
    ('sonar_tracking.nodes.active_detector:ActiveDetectorNode', 'threshold.maximum', 1.0, 'threshold.initial'),
    ('sonar_tracking.nodes.imm_ipda_tracker:ImmIpdaTrackerNode', 'existence.terminate', 0.6, 'initial'),
])
def test_a_cross_parameter_refusal_names_the_parameter_that_was_set(ros, inproc, node_path, name, value, other):
    """Through the service ``ros2 param set`` calls: the reason starts with the name and value set,
    even when the rule between settings is written from another setting's side."""
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter
    node = inproc(node_class(node_path))
    before = node.get_parameter(name).value
    setc = ros.node.create_client(SetParameters, f'/{node.get_name()}/set_parameters')
    try:
        assert setc.wait_for_service(timeout_sec=20.0)
        result = ros.call(setc, SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()]))
    finally:
        ros.node.destroy_client(setc)
    reason = result.results[0].reason
    assert not result.results[0].successful
    assert reason.startswith(f'{name} = {value!r} '), reason
    assert other in reason and node.get_parameter(name).value == before
