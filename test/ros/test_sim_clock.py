"""The clock model: /clock only on request, fine-grained and monotone, and one publisher per domain."""
from __future__ import annotations

import threading

import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

import sonar_tracking.msgs as ma
from sonar_tracking.ros.pacing import clock_steps

KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
MS = 10**6


def test_clock_steps_are_at_most_one_period_and_end_on_the_target():
    steps = clock_steps(1000 * MS, 1234 * MS + 7, 10 * MS, 10000)
    assert steps[-1] == 1234 * MS + 7 and len(steps) == 24
    gaps = [b - a for a, b in zip([1000 * MS] + steps, steps)]
    assert all(0 < g <= 10 * MS for g in gaps)
    assert clock_steps(None, 5, 10, 100) == [5]                 # the first value: the target itself
    assert clock_steps(5, 5, 10, 100) == [] and clock_steps(5, 3, 10, 100) == []   # never back
    assert len(clock_steps(0, 10**9, 1, 100)) == 100            # bounded work: wider steps beyond max_steps


def spin(executor) -> None:
    """``executor.spin()``, kept alive when the test destroys a subscription the executor waits on."""
    from rclpy.exceptions import InvalidHandle
    while True:
        try:
            executor.spin()
            return
        except InvalidHandle:
            continue


class Sims:
    """Simulators in this process (``start(namespace, **params)``), each spun by its own executor."""

    def __init__(self, context):
        self.context, self.started = context, []

    def start(self, namespace: str, **params):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter import Parameter

        from sonar_tracking.nodes.seaking_sim import SeaKingSimNode
        node = SeaKingSimNode(context=self.context, namespace=namespace,
                              parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        executor = SingleThreadedExecutor(context=self.context)
        executor.add_node(node)
        thread = threading.Thread(target=spin, args=(executor,), daemon=True)
        thread.start()
        self.started.append((node, executor, thread))
        return node

    def close(self):
        for node, executor, thread in self.started:
            executor.shutdown(timeout_sec=2.0)
            thread.join(timeout=5.0)
            node.destroy_node()


@pytest.fixture
def sims(graph_node):
    s = Sims(graph_node.context)
    yield s
    s.close()


def listen(ros, topic, msg_type, out, with_info=False):
    cb = (lambda m, info: out.append((m, info['publication_sequence_number']))) if with_info else out.append
    return ros.node.create_subscription(msg_type, topic, cb, KEEP_ALL)


@pytest.mark.ros
def test_no_clock_unless_asked_whatever_the_stamps(ros, sims):
    from sensor_msgs.msg import Image
    got = []
    sub = listen(ros, '/nc/sonar/sector', Image, got)
    try:
        sim = sims.start('/nc', scenario='fls3', rate=4.0)       # simulated stamps
        ros.wait(lambda: len(got) >= 3, 60.0, 'three sectors')
        assert not sim.pace.wall_stamps and ma.header_ns(got[0]) < 10**11
        assert ros.node.count_publishers('/clock') == 0
    finally:
        ros.node.destroy_subscription(sub)


@pytest.mark.ros
def test_the_clock_moves_in_small_steps_never_back_and_reaches_every_stamp_first(ros, sims):
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Image
    clocks, sectors = [], []
    subs = [listen(ros, '/clock', Clock, clocks, with_info=True), listen(ros, '/fg/sonar/sector', Image, sectors)]
    try:
        sim = sims.start('/fg', scenario='fls3', rate=4.0, publish_clock=True)
        ros.wait(lambda: len(sectors) >= 8, 60.0, 'eight sectors')
        assert sim.sim_clock.state == 'publishing'
        stamps = [ma.header_ns(m) for m in list(sectors)]
        # The probe may take a sector before the /clock message sent ahead of it on the other topic.
        ros.wait(lambda: clocks and ma.stamp_to_ns(clocks[-1][0].clock) >= stamps[-1], 60.0,
                 'the clock at the last sector')
        values = [(ma.stamp_to_ns(m.clock), seq) for m, seq in list(clocks)]
        ns = [v for v, _ in values]
        assert all(b >= a for a, b in zip(ns, ns[1:])), 'time never goes back'
        # Steps between messages read one after the other (a gap in the numbers: a message the probe missed).
        steps = [b - a for (a, sa), (b, sb) in zip(values, values[1:]) if sb == sa + 1]
        assert steps and max(steps) <= 10 * MS
        assert set(stamps) <= set(ns), '/clock reaches each stamp'
        between = [v for v in set(ns) if stamps[0] < v < stamps[1]]
        assert len(between) >= (stamps[1] - stamps[0]) // (10 * MS) - 1, 'not once per sector'
    finally:
        for s in subs:
            ros.node.destroy_subscription(s)


def diagnostics(ros, topic, out):
    from diagnostic_msgs.msg import DiagnosticArray
    return ros.node.create_subscription(DiagnosticArray, topic, lambda m: out.extend(m.status), 50)


@pytest.mark.ros
def test_of_two_simulators_started_together_only_the_lowest_gid_publishes_the_clock(ros, sims):
    from rosgraph_msgs.msg import Clock
    clocks, diag_a, diag_b = [], [], []
    subs = [listen(ros, '/clock', Clock, clocks), diagnostics(ros, '/a/diagnostics', diag_a),
            diagnostics(ros, '/b/diagnostics', diag_b)]
    try:
        # Far apart in simulated time: a single value of the other between two of one is time going back.
        a = sims.start('/a', scenario='fls3', rate=4.0, publish_clock=True)
        b = sims.start('/b', scenario='fls3', rate=4.0, publish_clock=True, stamp_offset=1000.0)
        ros.wait(lambda: 'claiming' not in (a.sim_clock.state, b.sim_clock.state), 20.0, 'both claims to end')
        keeper, other = (a, b) if a.sim_clock.gid < b.sim_clock.gid else (b, a)
        assert (keeper.sim_clock.state, other.sim_clock.state) == ('publishing', 'refused')
        assert f'{keeper.get_namespace()}/seaking_sim' in other.sim_clock.reason
        ros.wait(lambda: len(clocks) >= 50, 20.0, '/clock')
        ns = [ma.stamp_to_ns(m.clock) for m in list(clocks)]
        assert all(y >= x for x, y in zip(ns, ns[1:])), 'never both: time never goes back'
        assert [i.node_namespace for i in ros.node.get_publishers_info_by_topic('/clock')] == [keeper.get_namespace()]
        refused = diag_b if other is b else diag_a
        ros.wait(lambda: any('clock refused' in s.message for s in refused), 20.0, 'the refusal in the diagnostics')
        assert next(s for s in refused if 'clock refused' in s.message).level == b'\x01'
    finally:
        for s in subs:
            ros.node.destroy_subscription(s)


@pytest.mark.ros
def test_a_simulator_started_later_leaves_the_clock_to_the_running_one(ros, sims, launch):
    """The newcomer is another process, so its publisher GID may sort either way: it must refuse anyway."""
    from rosgraph_msgs.msg import Clock
    clocks, heard = [], []
    subs = [listen(ros, '/clock', Clock, clocks), diagnostics(ros, '/diagnostics', heard)]
    try:
        first = sims.start('/first', scenario='fls3', rate=1.0, stamps='sim', publish_clock=True)
        ros.wait(lambda: first.sim_clock.state == 'publishing' and clocks, 20.0, 'the first clock')
        proc = launch('seaking_sim', 'scenario:=fls3', 'rate:=1.0', 'publish_clock:=true', 'stamp_offset:=1000.0')
        ros.wait(lambda: any('clock refused' in s.message for s in heard), 60.0, 'the newcomer to refuse')
        assert first.sim_clock.state == 'publishing'
        ns = [ma.stamp_to_ns(m.clock) for m in list(clocks)]
        assert all(y >= x for x, y in zip(ns, ns[1:])) and ns[-1] < 1000 * 10**9
        err = launch.stop(proc)
        assert '/first/seaking_sim' in err and 'does not publish /clock' in err
    finally:
        for s in subs:
            ros.node.destroy_subscription(s)


@pytest.mark.ros
def test_another_tool_publishing_the_clock_is_left_alone(ros, sims):
    """A bag replay with --clock, say: the simulator refuses and names it."""
    from rosgraph_msgs.msg import Clock
    pub = ros.node.create_publisher(Clock, '/clock', 10)
    ticks = [0]

    def tick():
        ticks[0] += 1
        pub.publish(Clock(clock=ma.ns_to_stamp(ticks[0] * 50 * MS)))
    timer = ros.node.create_timer(0.05, tick)
    try:
        ros.wait(lambda: ticks[0] >= 2, 20.0, 'the other clock')
        sim = sims.start('/tool', scenario='fls3', rate=4.0, publish_clock=True)
        ros.wait(lambda: sim.sim_clock.state != 'claiming', 20.0, 'the claim to end')
        assert sim.sim_clock.state == 'refused' and '/sonar_tracking_test_probe' in sim.sim_clock.reason
        assert ros.node.count_publishers('/clock') == 1
    finally:
        ros.node.destroy_timer(timer)
        ros.node.destroy_publisher(pub)
