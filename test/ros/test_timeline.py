"""The one time rule (sonar_tracking.ros.timeline) and stamp pairing (sonar_tracking.msgs.pairing)."""
from sonar_tracking.msgs import StampPairer
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


def test_a_restart_keeps_the_new_recordings_parts_and_gives_up_the_old_ones():
    """A looping bag: the image topic runs ahead of the info topic, so parts of the new pass wait in
    the pairer when the jump back shows; they must still pair, and the old pass's parts go."""
    p = StampPairer(('image', 'info'), max_pending=4)
    for s in (27, 28, 29):
        p.add('image', s, f'i{s}')
    assert p.add('info', 27, 'n27')['image'] == 'i27' and p.add('info', 28, 'n28')['image'] == 'i28'
    for s in (0, 1):
        p.add('image', s, f'i{s}')                     # the new pass, ahead of its infos
    assert p.add('info', 0, 'n0') == {'image': 'i0', 'info': 'n0'}    # the node sees time go back
    assert p.pop_dropped() == []
    p.restart(28)
    assert p.pop_dropped() == [(29, ('image',))]      # the old pass's last image can never pair
    assert p.add('info', 1, 'n1') == {'image': 'i1', 'info': 'n1'}    # kept across the restart


def test_a_restart_forgets_stamps_pushed_out_in_the_old_recording():
    p = StampPairer(('image', 'info'), max_pending=1)
    p.add('image', 5, 'old5')
    p.add('image', 6, 'i6')                            # pushes 5 out: a late info 5 would be dropped
    assert p.pop_dropped() == [(5, ('image',))]
    assert p.add('info', 6, 'n6')['image'] == 'i6'
    p.restart(6)
    assert p.add('image', 5, 'new5') is None and p.add('info', 5, 'n5')['image'] == 'new5'   # the loop reuses 5
