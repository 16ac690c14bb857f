"""/diagnostics that cannot go stale: the rate decays when input stops, silence is reported after a
stated number of missed periods, and a restart or a parameter change is reported at once."""
from __future__ import annotations

import re

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus

import sonar_tracking.msgs as ma
from sonar_tracking.core.sector import SectorGeometry
from sonar_tracking.ros.diagnostics import STALE_PERIODS, StageDiagnostics

GEOM = SectorGeometry(angle_min=-0.4, angle_increment=0.01, n_beams=81, range_min=1.0, range_max=30.0, n_bins=150)


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def report(diag: StageDiagnostics) -> tuple[bytes, str, dict[str, str]]:
    st = diag.array(ma.ns_to_stamp(0)).status[0]
    return st.level, st.message, {kv.key: kv.value for kv in st.values}


def fed(period: float, n: int) -> tuple[StageDiagnostics, FakeClock]:
    clock = FakeClock()
    diag = StageDiagnostics('test: stage', clock=clock)
    for _ in range(n):
        clock.t += period
        diag.done(0.0)
    return diag, clock


def test_rate_is_exact_while_input_comes_and_decays_to_zero_once_it_stops():
    diag, clock = fed(0.1, 50)
    level, message, values = report(diag)
    assert level == DiagnosticStatus.OK and message == 'ok'
    assert float(values['rate_hz']) == pytest.approx(10.0, rel=1e-6)
    assert float(values['expected_period_s']) == pytest.approx(0.1, rel=1e-6)
    rates = []
    for _ in range(30):
        clock.t += 0.5
        rates.append(diag.rate())
    assert all(b <= a for a, b in zip(rates, rates[1:])) and rates[0] < 10.0
    assert rates[-1] == 0.0        # 15 s of silence: nothing left in the window


def test_silence_warns_after_the_stated_number_of_missed_periods():
    diag, clock = fed(0.5, 10)           # 2 Hz: stale after 3 periods = 1.5 s
    assert diag.stale_after() == pytest.approx(STALE_PERIODS * 0.5)
    clock.t += 1.4
    assert report(diag)[0] == DiagnosticStatus.OK
    clock.t += 0.2
    level, message, values = report(diag)
    assert level == DiagnosticStatus.WARN and 'no input for 1.6 s (expected every 0.5 s)' in message
    assert float(values['last_input_age_s']) == pytest.approx(1.6)
    diag.done(0.0)                        # input again: ok at once
    assert report(diag)[:2] == (DiagnosticStatus.OK, 'ok')


def test_a_fast_input_is_not_stale_between_two_messages():
    diag, clock = fed(0.01, 100)          # 100 Hz: three periods are 30 ms, but a report comes once a second
    clock.t += 0.5
    assert report(diag)[0] == DiagnosticStatus.OK
    clock.t += 0.6
    assert 'no input for 1.1 s' in report(diag)[1]


def test_one_input_and_then_silence_is_reported_too():
    diag, clock = fed(1.0, 1)
    assert report(diag)[0] == DiagnosticStatus.OK
    clock.t += STALE_PERIODS * StageDiagnostics.UNKNOWN_PERIOD + 0.1
    level, message, _ = report(diag)
    assert level == DiagnosticStatus.WARN and 'no period known yet' in message


def test_levels_before_input_on_drops_idle_and_standing_conditions():
    clock = FakeClock()
    diag = StageDiagnostics('test: stage', clock=clock, what='sector')
    assert report(diag)[:2] == (DiagnosticStatus.STALE, 'no sector yet')
    diag.drop('malformed', 3)
    level, message, values = report(diag)
    assert level == DiagnosticStatus.WARN and '3 messages dropped since the last report' in message
    assert values['dropped_malformed'] == '3'
    assert report(diag)[0] == DiagnosticStatus.OK        # a new period: the drops were reported
    diag.idle = 'scenario finished'
    clock.t += 100.0
    assert report(diag)[:2] == (DiagnosticStatus.OK, 'scenario finished')
    diag.condition('clock', 'clock refused: /clock is already published by /other')
    level, message, _ = report(diag)
    assert level == DiagnosticStatus.WARN and message.startswith('clock refused')
    diag.condition('clock', None)
    assert report(diag)[0] == DiagnosticStatus.OK


def sector(t: float, seed: int = 0):
    a = np.random.default_rng(seed + int(t * 10)).exponential(1.0, GEOM.shape).astype(np.float32)
    ns = int(round(t * 1e9))
    info = ma.geometry_to_scan(GEOM, amplitudes=a.astype(float), stamp_ns=ns)
    return ma.array_to_image(a, '32FC1', stamp_ns=ns), info


@pytest.fixture
def detector(graph_node):
    """An active_detector in this process that no executor spins: only what its callbacks publish
    synchronously is published (its once-a-second timer never runs)."""
    from sonar_tracking.nodes.active_detector import ActiveDetectorNode
    node = ActiveDetectorNode(context=graph_node.context)
    reports = []
    node.pub_diag.publish = reports.append
    subs = {s.topic_name: s for s in node.subscriptions}

    def feed(t):
        img, info = sector(t)
        subs['/sonar/sector'].callback(img)
        subs['/sonar/sector_info'].callback(info)
    node.feed, node.reports = feed, reports
    yield node
    node.destroy_node()


def values(report_msg) -> dict[str, str]:
    return {kv.key: kv.value for kv in report_msg.status[0].values}


@pytest.mark.ros
def test_a_restart_after_time_went_back_is_reported_at_once(detector):
    for t in (11.0, 12.0, 13.0):
        detector.feed(t)
    assert detector.diag.processed == 3 and detector.reports == []
    detector.feed(1.0)                    # 12 s back: a new recording
    assert len(detector.reports) == 1, 'the restart published a report before the next input'
    v = values(detector.reports[0])
    assert v['restarts'] == '1' and 'time went back by 12.000 s' in v['last_restart']


@pytest.mark.ros
def test_a_parameter_change_is_reported_at_once(detector):
    from rclpy.parameter import Parameter
    detector.feed(1.0)
    assert detector.set_parameters([Parameter('esc.enabled', value=False)])[0].successful
    assert len(detector.reports) == 1 and not detector.detector.enabled
    assert values(detector.reports[0])['last_parameter_change'] == 'esc.enabled=False'


@pytest.mark.ros
def test_a_node_whose_input_stops_reports_it_and_its_rate_decays(ros, inproc):
    """Over DDS: sectors at 10 Hz, then none; the once-a-second report goes from OK to WARN."""
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import Image, LaserScan

    from sonar_tracking.nodes.active_detector import ActiveDetectorNode
    heard = []
    sub = ros.node.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: heard.extend(s for s in m.status if s.name == 'active_detector: detection'), 50)
    pub_img = ros.node.create_publisher(Image, '/sonar/sector', 50)
    pub_info = ros.node.create_publisher(LaserScan, '/sonar/sector_info', 50)
    try:
        node = inproc(ActiveDetectorNode)
        ros.wait(lambda: pub_img.get_subscription_count() and pub_info.get_subscription_count(), 20.0, 'matching')
        timer_sent = [0]

        def send():                        # a timer of the probe, not sleeps: 10 sectors 0.1 s apart
            if timer_sent[0] < 10:
                timer_sent[0] += 1
                img, info = sector(float(timer_sent[0]))
                pub_img.publish(img)
                pub_info.publish(info)
        timer = ros.node.create_timer(0.1, send)
        ros.wait(lambda: node.diag.processed == 10, 20.0, 'ten sectors')
        ros.node.destroy_timer(timer)
        first = len(heard)
        ros.wait(lambda: any('no input for' in s.message for s in heard[first:]), 20.0, 'a report of the silence')
        stale = next(s for s in heard[first:] if 'no input for' in s.message)
        assert stale.level == DiagnosticStatus.WARN and re.search(r'expected every 0\.\d+ s', stale.message)
        # 10 Hz while it came; after more than a second of silence at most 9 intervals / 1.8 s
        assert float(dict((kv.key, kv.value) for kv in stale.values)['rate_hz']) < 6.0
    finally:
        ros.node.destroy_subscription(sub)
        ros.node.destroy_publisher(pub_img)
        ros.node.destroy_publisher(pub_info)
