"""Every message a node receives, or that the middleware lost on its way, is counted once under its
true reason: bursts at 1 kHz, pairing under a bounded queue, full subscription queues."""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import sonar_tracking.msgs as ma
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.msgs.pairing import DUPLICATE, EVICTED, UNPAIRED, StampPairer
from sonar_tracking.ros.diagnostics import SequenceGaps

GEOM = SectorGeometry(angle_min=-0.4, angle_increment=0.01, n_beams=81, range_min=1.0, range_max=30.0, n_bins=150)

#: Drop reasons counted per message (a half, or a message lost before it was read); the others per sector.
PER_MESSAGE = {'unpaired', 'partner_lost', 'evicted', 'duplicate', 'bad_stamp', 'queue_overflow'}


def sector(t: float, nan: bool = False):
    rng = np.random.default_rng(int(round(t * 1000)))
    a = rng.exponential(1.0, GEOM.shape).astype(np.float32)
    if nan:
        a[5, 5] = np.nan
    ns = int(round(t * 1e9))
    info = ma.geometry_to_scan(GEOM, amplitudes=None if nan else a.astype(float), stamp_ns=ns)
    return ma.array_to_image(a, '32FC1', stamp_ns=ns), info


def messages_accounted(node) -> int:
    """Messages of the sector input that are processed, dropped, lost or still held."""
    dropped = node.diag.dropped
    sectors = node.diag.processed + sum(n for reason, n in dropped.items() if reason not in PER_MESSAGE)
    return 2 * sectors + sum(n for reason, n in dropped.items() if reason in PER_MESSAGE) + node.input.held


# -- the pairer ----------------------------------------------------------------------------------

def test_the_pairer_tells_evicted_from_unpaired_and_duplicate():
    p = StampPairer(('image', 'info'), max_pending=2)
    for s in (1, 2, 3):
        p.add('image', s, s)
    assert p.pop_dropped_with_reasons() == [(1, ('image',), EVICTED)]
    assert p.add('info', 1, 'late') is None
    assert p.pop_dropped_with_reasons() == [(1, ('info',), EVICTED)]     # its partner was pushed out
    p.add('image', 3, 'again')
    assert p.pop_dropped_with_reasons() == [(3, ('image',), DUPLICATE)]
    assert p.add('info', 3, 'n3') == {'image': 'again', 'info': 'n3'}
    assert p.pop_dropped_with_reasons() == [(2, ('image',), UNPAIRED)]  # 3 completed: 2's info never comes
    assert p.pending_parts == 0


def test_every_part_offered_to_the_pairer_is_accounted_for_once():
    rng = np.random.default_rng(7)
    p = StampPairer(('image', 'info', 'regions'), max_pending=5)
    offered = completed = given_up = 0
    for stamp in range(400):
        parts = [part for part in p.parts if rng.random() < 0.85]
        parts += [part for part in parts if rng.random() < 0.05]          # a few duplicates
        for part in rng.permutation(parts):
            delay = stamp + int(rng.integers(0, 8))                        # topics out of step
            offered += 1
            completed += 3 * (p.add(str(part), delay, part) is not None)
        given_up += sum(len(parts) for _, parts, _ in p.pop_dropped_with_reasons())
    assert completed + given_up + p.pending_parts == offered


# -- the sequence gaps ---------------------------------------------------------------------------

def test_sequence_gaps_count_lost_messages_of_one_publisher_only():
    g = SequenceGaps()
    assert g.lost(5, 1) == 0                       # the first message read: no claim about earlier ones
    assert g.lost(6, 1) == 0 and g.lost(9, 1) == 2
    assert g.lost(1, 1) == 0                       # a new publisher starts again at 1
    assert g.lost(4, 2) == 0 and g.lost(9, 2) == 0  # two publishers: their numbers interleave
    assert g.lost(10, 1) == 0 and g.lost(12, 1) == 1
    assert g.supported
    assert g.lost(None, 1) == 0 and g.supported is False   # an rmw that does not number messages


# -- a sector consumer, its callbacks fed directly ------------------------------------------------

@pytest.fixture
def detector(graph_node):
    """``detector(**params)``: an active_detector in this process, not spun: the test calls its callbacks."""
    from rclpy.parameter import Parameter

    from sonar_tracking.nodes.active_detector import ActiveDetectorNode
    made = []

    def make(**params):
        node = ActiveDetectorNode(context=graph_node.context,
                                  parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        node.subs = {s.topic_name: s for s in node.subscriptions}
        made.append(node)
        return node
    yield make
    for node in made:
        node.destroy_node()


@pytest.mark.ros
@pytest.mark.parametrize('max_pending', [None, 16])
def test_one_topic_running_ahead_pushes_out_no_partner_by_default(detector, max_pending):
    """40 images, then their 40 geometries (a burst in which one topic runs ahead): the default
    queue pairs them all; a queue of 16 pushes 24 out, counted as evicted, never as unpaired."""
    node = detector() if max_pending is None else detector(max_pending=max_pending)
    pairs = [sector(1.0 + 0.1 * k) for k in range(40)]
    for img, _ in pairs:
        node.subs['/sonar/sector'].callback(img)
    for _, info in pairs:
        node.subs['/sonar/sector_info'].callback(info)
    if max_pending is None:
        assert node.diag.processed == 40 and node.diag.dropped == {}
    else:
        assert node.diag.processed == 16 and node.diag.dropped == {'evicted': 48}
    assert messages_accounted(node) == 80


@pytest.mark.ros
def test_a_half_whose_partner_the_middleware_lost_is_counted_as_such(ros, detector):
    from sensor_msgs.msg import Image, LaserScan
    node = detector()
    # Gaps are read only while exactly one publisher is matched: these two, which publish nothing.
    pubs = [ros.node.create_publisher(Image, '/sonar/sector', 10),
            ros.node.create_publisher(LaserScan, '/sonar/sector_info', 10)]
    try:
        ros.wait(lambda: all(node.subs[t].get_publisher_count() == 1 for t in ('/sonar/sector', '/sonar/sector_info')),
                 20.0, 'the publishers to match')
        img, info = node.subs['/sonar/sector'].callback, node.subs['/sonar/sector_info'].callback
        s = {t: sector(t) for t in (1.0, 2.0, 3.0, 4.0, 5.0)}
        img(s[1.0][0], {'publication_sequence_number': 1})
        info(s[1.0][1], {'publication_sequence_number': 1})
        img(s[2.0][0], {'publication_sequence_number': 2})
        info(s[3.0][1], {'publication_sequence_number': 3})   # info 2 was lost in the middleware
        img(s[3.0][0], {'publication_sequence_number': 3})
        img(s[4.0][0], {'publication_sequence_number': 4})    # info 4 is never sent
        info(s[5.0][1], {'publication_sequence_number': 4})
        img(s[5.0][0], {'publication_sequence_number': 5})
        assert node.diag.processed == 3
        assert node.diag.dropped == {'queue_overflow': 1, 'partner_lost': 1, 'unpaired': 1}
        assert messages_accounted(node) == 9
    finally:
        for p in pubs:
            ros.node.destroy_publisher(p)


# -- over DDS --------------------------------------------------------------------------------------

@pytest.mark.ros
def test_messages_lost_from_a_full_queue_are_counted(ros, inproc):
    """A node whose callback is held while 99 messages arrive keeps the last 5 (its queue): the 94
    others are counted as lost, from the gap in the publisher's sequence numbers."""
    from std_msgs.msg import UInt32

    from sonar_tracking.ros.node import InputConfig, SonarNode
    entered, release = threading.Event(), threading.Event()

    class Held(SonarNode):
        def __init__(self, **kwargs):
            super().__init__('held', InputConfig(), 'held: test', **kwargs)
            self.got = []
            self.subscribe(UInt32, '/h3_drop_counting/held', self.on_msg, 5)

        def on_msg(self, msg):
            entered.set()
            release.wait(30.0)
            self.got.append(msg.data)
            self.diag.done(time.perf_counter())

    node = inproc(Held)
    pub = ros.node.create_publisher(UInt32, '/h3_drop_counting/held', 200)
    try:
        ros.wait(lambda: pub.get_subscription_count() == 1, 20.0, 'matching')
        pub.publish(UInt32(data=0))
        ros.wait(entered.is_set, 20.0, 'the first message in the callback')
        for k in range(1, 100):
            pub.publish(UInt32(data=k))
        from rclpy.duration import Duration
        assert pub.wait_for_all_acked(Duration(seconds=20.0)), 'the reader holds the last messages'
        release.set()
        ros.wait(lambda: node.diag.processed + node.diag.dropped.get('queue_overflow', 0) == 100, 20.0,
                 'every message processed or counted as lost')
        assert node.got == [0, 95, 96, 97, 98, 99] and node.diag.dropped == {'queue_overflow': 94}
    finally:
        release.set()
        ros.node.destroy_publisher(pub)


@pytest.mark.ros
@pytest.mark.parametrize('nan, n', [(False, 200), (True, 300)])
def test_a_burst_at_1_khz_is_counted_message_for_message_under_true_reasons(ros, inproc, nan, n):
    """200 valid sector pairs, or 300 with a NaN amplitude, published at 1 kHz to an active_detector:
    once its counts settle, processed + dropped by reason + lost in the middleware account for every
    message sent, and no half is called unpaired while its partner was sent."""
    from sensor_msgs.msg import Image, LaserScan

    from sonar_tracking.nodes.active_detector import ActiveDetectorNode
    node = inproc(ActiveDetectorNode)
    pub_img = ros.node.create_publisher(Image, '/sonar/sector', 10)
    pub_info = ros.node.create_publisher(LaserScan, '/sonar/sector_info', 10)
    try:
        ros.wait(lambda: pub_img.get_subscription_count() and pub_info.get_subscription_count(), 20.0, 'matching')
        msgs = [sector(1.0 + 0.1 * k, nan) for k in range(n)]
        start = time.perf_counter()
        for k, (img, info) in enumerate(msgs):
            pub_img.publish(img)
            pub_info.publish(info)
            while time.perf_counter() < start + (k + 1) * 1e-3:   # 1 kHz: pacing, not waiting on a result
                pass
        ros.wait(lambda: messages_accounted(node) == 2 * n, 60.0, f'{2 * n} messages accounted for')
        dropped = dict(node.diag.dropped)
        allowed = {'queue_overflow', 'partner_lost'} | ({'malformed'} if nan else set())
        assert set(dropped) <= allowed, dropped
        assert dropped.get('partner_lost', 0) <= dropped.get('queue_overflow', 0)
        if nan:
            assert node.diag.processed == 0 and dropped['malformed'] >= 1
        else:
            assert node.diag.processed >= 1
    finally:
        ros.node.destroy_publisher(pub_img)
        ros.node.destroy_publisher(pub_info)
