"""The one time rule (sonar_tracking.ros.timeline) and stamp pairing (msg_adapters.pairing)."""
from msg_adapters import StampPairer
from sonar_tracking.ros.timeline import LATE, NEW, RESET, TimeGuard


def test_late_stamps_are_dropped_and_big_jumps_back_reset():
    g = TimeGuard()
    assert g.check(5 * 10**9, 3.0) == (NEW, 0.0)
    g.accept(5 * 10**9)
    assert g.check(5 * 10**9, 3.0)[0] == LATE                 # a repeat
    assert g.check(4_500_000_000, 3.0) == (LATE, 0.5)         # 0.5 s old: dropped, nothing changes
    assert g.last_ns == 5 * 10**9
    assert g.check(1 * 10**9, 3.0) == (RESET, 4.0)            # a looping bag
    assert g.check(6 * 10**9, 3.0)[0] == NEW


def test_pairer_completes_frames_of_any_parts_and_gives_up_older_ones():
    p = StampPairer(('image', 'info', 'regions'), max_pending=2)
    assert p.add('image', 1, 'i1') is None and p.add('info', 1, 'n1') is None
    assert p.add('image', 2, 'i2') is None
    assert p.add('info', 2, 'n2') is None
    assert p.add('regions', 2, 'r2') == {'image': 'i2', 'info': 'n2', 'regions': 'r2'}
    assert p.pop_dropped() == [(1, ('image', 'info'))]        # stamp 1 can no longer complete
    assert p.missing(('image', 'info')) == ('regions',)
    for s in (4, 5, 3):
        p.add('image', s, s)
    assert p.pop_dropped() == [(3, ('image',))]               # at most two stamps wait: the oldest goes
    assert p.add('info', 3, 'late') is None and p.pop_dropped() == [(3, ('info',))]   # and stays gone
    p.add('image', 5, 'again')
    assert p.pop_dropped() == [(5, ('image',))]               # a repeated part replaces the first
    assert p.add('info', 4, 'n4') is None and p.add('regions', 4, 'r4')['image'] == 4
