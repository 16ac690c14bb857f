"""A node's state on ``~/status`` and in ``/diagnostics``: starting, learning (structure warm-up), ready."""
from __future__ import annotations

import json
import threading

import numpy as np
import pytest

from sonar_tracking.core.structure import StructureConfig, WarmUp
from sonar_tracking.ros.status import LEARNING, READY, STARTING, least_ready, parse_status, warmup_left


def test_seconds_left_of_the_structure_warm_up():
    on = StructureConfig(enabled=True, min_echo_time=5.0)
    warm = WarmUp()
    assert warmup_left(warm, StructureConfig(), None) == 0.0                        # no structure rejection
    assert warmup_left(warm, StructureConfig(enabled=True, warmup=False), 3.0) == 0.0
    assert warmup_left(warm, on, None) == 5.0                                       # before any input
    assert warm.holding(100.0, on)                                                  # the first scan starts it
    assert warmup_left(warm, on, 100.0) == 5.0
    assert warmup_left(warm, on, 103.5) == pytest.approx(1.5)
    assert warmup_left(warm, on, 105.0) == 0.0
    assert warm.start == 100.0                                                      # asking did not move it


def test_least_ready_and_foreign_records():
    assert least_ready([READY, LEARNING]) == LEARNING
    assert least_ready([READY, None]) == STARTING
    assert least_ready([]) == READY
    assert parse_status('{"state": "ready", "node": "/x"}')['node'] == '/x'
    assert parse_status('OK') is None and parse_status('{"state": "fine"}') is None


@pytest.mark.ros
def test_active_detector_says_starting_then_learning_then_ready(ros, graph_node):
    """Through DDS: the detector says ``starting`` while it is built, ``learning`` (with the seconds of
    input left) while the structure background holds detections back, ``ready`` once it has learnt
    for ``structure.min_echo_time`` of stamps; ``/diagnostics`` says the same."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image, LaserScan, PointCloud2
    from std_msgs.msg import String

    import sonar_tracking.msgs as ma
    from sonar_tracking.nodes.active_detector import ActiveDetectorNode
    from sonar_tracking.sim import SimConfig, Simulator

    keep_all = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
    node = ros.node
    records, diags, detections = [], [], []
    lock = threading.Lock()

    def on_diag(msg):
        with lock:
            diags.extend({'message': st.message, **{kv.key: kv.value for kv in st.values}}
                         for st in msg.status if st.name == 'active_detector: detection')
    subs = [node.create_subscription(String, '/active_detector/status',
                                     lambda m: records.append(json.loads(m.data)), latched),
            node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, keep_all),
            node.create_subscription(PointCloud2, '/detections', detections.append, keep_all)]
    pub_img = node.create_publisher(Image, '/sonar/sector', keep_all)
    pub_info = node.create_publisher(LaserScan, '/sonar/sector_info', keep_all)
    det = ActiveDetectorNode(context=graph_node.context, parameter_overrides=[
        Parameter('structure.enabled', value=True), Parameter('structure.min_echo_time', value=2.0)])
    executor = None
    try:
        # Built, not spinning yet: starting, on the latched topic and in the diagnostics sent meanwhile.
        ros.wait(lambda: records, 20.0, 'the first status')
        assert records[-1]['state'] == STARTING and records[-1]['node'] == '/active_detector'
        ros.wait(lambda: any(d['state'] == STARTING for d in diags), 20.0, 'diagnostics while starting')
        executor = SingleThreadedExecutor(context=graph_node.context)
        executor.add_node(det)
        thread = threading.Thread(target=executor.spin, daemon=True)
        thread.start()
        ros.wait(lambda: records[-1]['state'] == LEARNING, 20.0, 'learning before any input')
        assert records[-1]['seconds_left'] == 2.0
        ros.wait(lambda: pub_img.get_subscription_count() and pub_info.get_subscription_count(), 20.0, 'the detector')
        sim = Simulator(SimConfig.for_scenario('scenario1'), np.random.default_rng(5))
        for k in range(6):              # stamps 10.0 .. 12.5 s: held through 11.5 s
            s = sim.next_sector()
            ns = int((10.0 + 0.5 * k) * 1e9)
            pub_img.publish(ma.array_to_image(s.amplitudes, stamp_ns=ns, frame_id='sonar'))
            pub_info.publish(ma.geometry_to_scan(s.geometry, stamp_ns=ns, frame_id='sonar'))
            ros.wait(lambda k=k: len(detections) > k, 20.0, f'detections of sector {k}')
            if k == 2:   # 1 s of input learnt, 1 s left
                ros.wait(lambda: records[-1].get('seconds_left') == 1.0, 10.0, 'one second left')
                assert records[-1]['state'] == LEARNING
                ros.wait(lambda: any(d['state'] == LEARNING and d['warmup_left_s'] == '1.0' for d in diags),
                         10.0, 'diagnostics while learning')
        ros.wait(lambda: records[-1]['state'] == READY, 10.0, 'ready after 2 s of input')
        ros.wait(lambda: diags[-1]['state'] == READY, 10.0, 'diagnostics ready')
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=2.0)
        det.destroy_node()
        for sub in subs:
            node.destroy_subscription(sub)
        node.destroy_publisher(pub_img)
        node.destroy_publisher(pub_info)
    held = [ma.cloud_to_array(m).size for m in detections]
    assert len(held) == 6 and held[:4] == [0, 0, 0, 0]          # nothing went out while learning
    states = [r['state'] for r in records]
    assert states == sorted(states, key=[STARTING, LEARNING, READY].index)   # never back while input comes
    learning = [d for d in diags if d['state'] == LEARNING]
    assert all('learning the structure background' in d['message'] for d in learning)
    assert diags[-1]['warmup_left_s'] == '0.0' and 'learning' not in diags[-1]['message']
