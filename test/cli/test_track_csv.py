"""``sonar_eval track``: CSV in, tracks out, bad rows reported by line, parameter files."""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pytest

from sonar_tracking.cli import track_csv
from sonar_tracking.core.tracking import ImmIpdaTracker, TrackerConfig

CONFIG = Path(__file__).resolve().parents[2] / 'config' / 'imm_ipda.yaml'


def scenario(seed=50, n_scans=25, n_clutter=5):
    """Rows (scan, t, x, y, r_xx, r_xy, r_yy, clutter_density) and the truth per scan."""
    rng = np.random.default_rng(seed)
    rows, truth = [], []
    pos, vel = np.array([100.0, -50.0]), np.array([6.0, 3.0])
    for k in range(n_scans):
        p = pos + vel * k
        truth.append(p)
        pts = [p + rng.normal(0, 3.0, 2)] + list(p + rng.uniform(-300, 300, (n_clutter, 2)))
        for q in pts:
            rows.append((k, 10.0 + 2.0 * k, q[0], q[1], 9.0, 1.0, 9.0, 2e-5))
    return rows, np.array(truth)


def write_csv(path: Path, rows, header=('scan', 't', 'x', 'y', 'r_xx', 'r_xy', 'r_yy', 'clutter_density')):
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            w.writerow(r)


def read_output(path: Path) -> list[dict]:
    with open(path, newline='') as f:
        return list(csv.DictReader(f))


def run(capsys, *argv):
    code = track_csv.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_tracks_recorded_detections_exactly_as_the_tracker_does(tmp_path, capsys):
    rows, truth = scenario()
    write_csv(tmp_path / 'det.csv', rows)
    code, _, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', tmp_path / 'tracks.csv')
    assert code == 0, err
    out = read_output(tmp_path / 'tracks.csv')
    assert list(out[0]) == list(track_csv.OUTPUT_COLUMNS)
    # The same numbers as the tracker run directly on the same scans.
    trk = ImmIpdaTracker(TrackerConfig())
    expected = []
    for k in range(len(truth)):
        sel = [r for r in rows if r[0] == k]
        z = np.array([[r[2], r[3]] for r in sel])
        R = np.broadcast_to(np.array([[9.0, 1.0], [1.0, 9.0]]), (len(sel), 2, 2))
        for rec in trk.step(10.0 + 2.0 * k, z, R, np.full(len(sel), 2e-5)):
            expected.append((k, int(rec['track_id']), rec['x'], rec['existence'], int(rec['confirmed'])))
    assert len(out) == len(expected)
    for row, (k, tid, x, e, c) in zip(out, expected):
        assert (int(row['scan']), int(row['track_id']), int(row['confirmed'])) == (k, tid, c)
        assert float(row['x']) == pytest.approx(x, rel=1e-9) and float(row['existence']) == pytest.approx(e, rel=1e-9)
    last = [r for r in out if int(r['scan']) == len(truth) - 1 and r['confirmed'] == '1']
    assert len(last) == 1
    assert np.hypot(float(last[0]['x']) - truth[-1, 0], float(last[0]['y']) - truth[-1, 1]) < 10
    assert f'{len(truth)} scans' in err and 'written to' in err


def test_bad_rows_are_reported_by_line_number_and_the_rest_processed(tmp_path, capsys):
    rows, _ = scenario(n_scans=12, n_clutter=2)
    good = [','.join(map(str, r)) for r in rows]
    bad = {   # each placed among the rows of the scan it names
        'a,12,1,1,9,0,9,1e-5': 'scan',                       # scan not an integer
        '0,11,1,1,9,0,9,1e-5': 'differs from the time',      # wrong time for scan 0
        '1,12,abc,1,9,0,9,1e-5': "x = 'abc' is not a number",
        '2,14,nan,1,9,0,9,1e-5': 'not finite',
        '3,16,5,5,1,5,1,1e-5': 'not positive definite',
        '4,18,5,5,9,0,9,-1': 'clutter density',
        '5,20,5,5,9,,9,1e-5': 'r_xx, r_xy, r_yy must be given together',
        '6,22,5,5,9,0,9,1e-5,': 'x',                         # an extra cell is ignored: a good row
    }
    text = ['scan,t,x,y,r_xx,r_xy,r_yy,clutter_density']
    for k in range(12):
        text += good[3 * k:3 * k + 2] + [row for row in bad if row.split(',')[0] in (str(k), 'a' * (k == 0))]
        text += good[3 * k + 2:3 * k + 3]
    lines = {row: n for n, row in enumerate(text, start=1) if row in bad}
    (tmp_path / 'det.csv').write_text('\n'.join(text) + '\n')
    code, _, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', tmp_path / 'out.csv')
    assert code == 0
    for row, reason in list(bad.items())[:-1]:
        hit = [ln for ln in err.splitlines() if ln.startswith(f'line {lines[row]}:')]
        assert hit and reason in hit[0] and hit[0].endswith('row skipped'), (row, err)
    assert f'line {lines["6,22,5,5,9,0,9,1e-5,"]}:' not in err
    assert f'{len(bad) - 1} bad rows skipped' in err
    out = read_output(tmp_path / 'out.csv')
    assert {int(r['scan']) for r in out} == set(range(12))


def test_a_bad_row_changes_nothing_else(tmp_path, capsys):
    """A bad row early in the file (of a later scan) neither starts, ends nor times a scan: the output is
    that of the file without it."""
    rows, _ = scenario(n_scans=15)
    write_csv(tmp_path / 'clean.csv', rows)
    code, _, err = run(capsys, '--input', tmp_path / 'clean.csv', '--output', tmp_path / 'clean_out.csv')
    assert code == 0 and 'reset' not in err and 'backwards' not in err
    text = (tmp_path / 'clean.csv').read_text().splitlines()
    for bad in ('7,24,oops,1,9,1,9,2e-5',          # not a number
                '7,24,1,1,1,5,1,2e-5',             # covariance not positive definite (the tracker's rule)
                '7,99,1,1,9,1,9,-2e-5'):           # clutter density negative, and a time scan 7 does not have
        dirty = [text[0], bad, *text[1:4], bad, *text[4:]]
        (tmp_path / 'dirty.csv').write_text('\n'.join(dirty) + '\n')
        code, _, err = run(capsys, '--input', tmp_path / 'dirty.csv', '--output', tmp_path / 'dirty_out.csv')
        assert code == 0
        assert [ln.split(':')[0] for ln in err.splitlines() if ln.startswith('line ')] == ['line 2', 'line 6']
        assert 'backwards' not in err and 'reset' not in err
        assert (tmp_path / 'dirty_out.csv').read_text() == (tmp_path / 'clean_out.csv').read_text()


def test_the_rows_of_a_scan_must_be_consecutive(tmp_path, capsys):
    (tmp_path / 'det.csv').write_text('scan,t,x,y\n0,0,0,0\n1,1,1,1\n0,0,5,5\n2,2,2,2\n')
    code, out, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', '-')
    assert code == 0
    assert 'line 4: scan 0 ended at line 2: the rows of a scan must be consecutive' in err
    # One track follows the points (init.exclude: all, the default, starts no track from a detection it validated).
    assert [int(r['scan']) for r in csv.DictReader(io.StringIO(out))] == [0, 1, 2]
    assert '3 scans, 3 detections used, 1 bad rows skipped' in err


def spreadsheet_forms(rows):
    """The same detections as different spreadsheets save them: ``{name: bytes}``."""
    header = ['Scan', 'T', 'X', 'Y', 'r_xx', 'r_xy', 'r_yy', 'clutter_density', 'note']
    notes = ['plain', 'with, comma', 'two\nlines', 'quote "q"', 'café']

    def table(delimiter=',', decimal='.', quoting=csv.QUOTE_MINIMAL, end='\r\n'):
        buf = io.StringIO()
        w = csv.writer(buf, delimiter=delimiter, quoting=quoting, lineterminator=end)
        w.writerow(header)
        for i, r in enumerate(rows):
            w.writerow([r[0]] + [repr(float(v)).replace('.', decimal) for v in r[1:]] + [notes[i % len(notes)]])
        return buf.getvalue()
    return {
        'excel utf-8 (BOM, CRLF)': b'\xef\xbb\xbf' + table().encode(),
        'all quoted, LF': table(quoting=csv.QUOTE_ALL, end='\n').encode(),
        'german excel (;, decimal comma)': table(';', ',').encode('cp1252'),
        'tab separated': table('\t').encode(),
        'old mac (CR only)': table(end='\r').replace('two\nlines', 'two lines').encode('mac_roman'),
    }


def test_reads_what_spreadsheets_write(tmp_path, capsys):
    rows, _ = scenario(n_scans=10)
    write_csv(tmp_path / 'plain.csv', rows)
    code, _, err = run(capsys, '--input', tmp_path / 'plain.csv', '--output', tmp_path / 'plain_out.csv')
    assert code == 0
    expected = (tmp_path / 'plain_out.csv').read_text()
    for name, data in spreadsheet_forms(rows).items():
        (tmp_path / 'in.csv').write_bytes(data)
        code, _, err = run(capsys, '--input', tmp_path / 'in.csv', '--output', tmp_path / 'out.csv')
        assert code == 0, (name, err)
        assert '0 bad rows skipped' in err, (name, err)
        assert (tmp_path / 'out.csv').read_text() == expected, name
        assert ('not UTF-8' in err) == (name in ('german excel (;, decimal comma)', 'old mac (CR only)')), (name, err)


def test_text_that_is_not_utf8_or_is_huge(tmp_path, capsys):
    rows, _ = scenario(n_scans=6, n_clutter=2)
    head = 'scan,t,x,y,r_xx,r_xy,r_yy,clutter_density,note\n'
    body = [','.join(map(str, r)) + ',ok' for r in rows]
    huge_field = '0,10,1,1,9,1,9,2e-5,' + 'x' * 200_000                 # over csv's 131,072-character field limit
    huge_line = '0,10,1,1,9,1,9,2e-5,"' + 'y' * (track_csv.MAX_LINE + 10) + '"'
    latin = '1,12,' + body[3].split(',', 2)[2].replace(',ok', ',déjà vu')
    lines = [head.strip(), *body[:3], huge_field, huge_line, body[3], latin, *body[4:]]
    (tmp_path / 'det.csv').write_bytes('\n'.join(lines[:7]).encode() + b'\n' + lines[7].encode('latin-1') + b'\n'
                                      + '\n'.join(lines[8:]).encode() + b'\n')
    code, _, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', tmp_path / 'out.csv')
    assert code == 0, err
    assert 'line 5: unreadable CSV (field larger than field limit (131072)); row skipped' in err
    assert f'line 6: the line is longer than {track_csv.MAX_LINE} bytes; row skipped' in err
    assert 'warning: line 8 is not UTF-8' in err and 'Latin-1' in err
    assert '2 bad rows skipped' in err and '6 scans' in err
    (tmp_path / 'u16.csv').write_bytes(head.encode('utf-16'))
    code, _, err = run(capsys, '--input', tmp_path / 'u16.csv', '--output', tmp_path / 'out.csv')
    assert code == 2 and 'UTF-16' in err and 'Traceback' not in err


def test_large_files_are_streamed(tmp_path):
    """The first scan reaches the tracker after a bounded part of the file was read."""
    rows, _ = scenario(n_scans=4000, n_clutter=9)                       # 40,000 rows, about 2.6 MB
    write_csv(tmp_path / 'big.csv', rows)

    class Counting(io.FileIO):
        def read(self, n=-1):
            data = super().read(n)
            self.total = getattr(self, 'total', 0) + len(data)
            return data
    raw = Counting(tmp_path / 'big.csv')
    reader = track_csv.DetectionReader(raw, io.StringIO(), TrackerConfig())
    scans = reader.scans()
    first = next(scans)
    size = (tmp_path / 'big.csv').stat().st_size
    assert first.number == 0 and len(first.z) == 10
    assert raw.total <= (1 << 20) + (64 << 10) < size
    assert sum(1 for _ in scans) == 3999 and reader.n_scans == 4000


def test_optional_columns_empty_scans_and_time_going_back(tmp_path, capsys):
    text = 'scan,t,x,y\n0,0,0,0\n1,1,1,1\n2,2,,\n3,3,3,3\n4,1,0,0\n4,1,100,100\n'
    (tmp_path / 'det.csv').write_text(text)
    code, out, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', '-')
    assert code == 0, err
    assert 'no clutter_density column' in err and 'time went backwards' in err
    rows = list(csv.DictReader(io.StringIO(out)))
    assert {int(r['scan']) for r in rows} == {0, 1, 2, 3, 4}      # scan 2 had no detections but tracks
    ids = {s: {int(r['track_id']) for r in rows if int(r['scan']) == s} for s in range(5)}
    assert min(ids[4]) > max(ids[3]), 'after the restart tracks get new ids'


def test_parameter_files(tmp_path, capsys):
    rows, _ = scenario(n_scans=5)
    write_csv(tmp_path / 'det.csv', rows)
    code, _, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', tmp_path / 'a.csv', '--params', CONFIG)
    assert code == 0, err
    (tmp_path / 'plain.yaml').write_text('imm:\n  models: cv\ndetection.probability: 0.8\n')
    code, _, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', tmp_path / 'b.csv',
                       '--params', tmp_path / 'plain.yaml', '--confirmed-only')
    assert code == 0, err
    (tmp_path / 'typo.yaml').write_text('imm_ipda_tracker:\n  ros__parameters:\n    detection.probabilty: 0.8\n')
    code, _, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', tmp_path / 'c.csv',
                       '--params', tmp_path / 'typo.yaml')
    assert code == 2 and 'detection.probabilty' in err
    (tmp_path / 'range.yaml').write_text('detection.probability: 2.0\n')
    code, _, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', tmp_path / 'c.csv',
                       '--params', tmp_path / 'range.yaml')
    assert code == 2 and 'detection.probability' in err


def test_unusable_input_exits_2_with_the_reason(tmp_path, capsys):
    (tmp_path / 'nocol.csv').write_text('scan,t,x\n0,0,1\n')
    code, _, err = run(capsys, '--input', tmp_path / 'nocol.csv', '--output', tmp_path / 'o.csv')
    assert code == 2 and "lacks column(s) ['y']" in err
    code, _, err = run(capsys, '--input', tmp_path / 'missing.csv', '--output', tmp_path / 'o.csv')
    assert code == 2 and 'cannot read' in err
    (tmp_path / 'empty.csv').write_text('')
    code, _, err = run(capsys, '--input', tmp_path / 'empty.csv', '--output', tmp_path / 'o.csv')
    assert code == 2 and 'empty' in err


@pytest.mark.parametrize('header', ['scan,t,x,y,x', 'scan,t,x,y,r_xx,r_xy,r_yy,R_XX', 'Scan,scan,t,x,y'])
def test_a_column_named_twice_is_refused(tmp_path, capsys, header):
    (tmp_path / 'det.csv').write_text(header + '\n' + ','.join(['1'] * len(header.split(','))) + '\n')
    code, out, err = run(capsys, '--input', tmp_path / 'det.csv', '--output', tmp_path / 'o.csv')
    twice = {'scan,t,x,y,x': "['x']", 'scan,t,x,y,r_xx,r_xy,r_yy,R_XX': "['r_xx']", 'Scan,scan,t,x,y': "['scan']"}
    assert code == 2 and f'names column(s) {twice[header]} more than once' in err, err
    assert not (tmp_path / 'o.csv').exists()


class Endless(io.RawIOBase):
    """``prefix`` then the same byte for ever (as /dev/zero gives it); counts what was read."""

    def __init__(self, prefix: bytes = b'', fill: bytes = b'\0'):
        self.prefix, self.fill, self.total = prefix, fill, 0

    def readable(self):
        return True

    def readinto(self, buf):
        n = len(buf)
        head, self.prefix = self.prefix[:n], self.prefix[n:]
        buf[:len(head)] = head
        buf[len(head):n] = self.fill * (n - len(head))
        self.total += n
        return n


def test_input_without_line_ends_is_refused_after_a_bounded_read(tmp_path, capsys):
    code, _, err = run(capsys, '--input', '/dev/zero', '--output', tmp_path / 'o.csv')
    assert code == 2 and 'where the header belongs, is longer than' in err, err
    # The same from a stream: refused once one line has run past the bound, not at the end of the input.
    raw = Endless()
    with pytest.raises(track_csv.InputError, match='where the header belongs'):
        track_csv.DetectionReader(raw, io.StringIO(), TrackerConfig())
    assert raw.total <= track_csv.MAX_LINE + (2 << 20)
    raw = Endless(b'scan,t,x,y\n0,0,1,1\n1,1,2,2\n')
    reader = track_csv.DetectionReader(raw, io.StringIO(), TrackerConfig())
    with pytest.raises(track_csv.InputError, match='without a line end'):
        list(reader.scans())
    assert raw.total <= track_csv.MAX_RUN + (2 << 20)
    # Blank lines for ever before a header, or a line csv refuses where it belongs: refused too.
    raw = Endless(fill=b'\n')
    with pytest.raises(track_csv.InputError, match=f'no header in the first {track_csv.MAX_HEADER_LINES} lines'):
        track_csv.DetectionReader(raw, io.StringIO(), TrackerConfig())
    assert raw.total <= (2 << 20)
    with pytest.raises(track_csv.InputError, match='line 1, where the header belongs, is not readable as CSV'):
        track_csv.DetectionReader(io.BytesIO(b'"' + b'x' * 200_000 + b'"\nscan,t,x,y\n'), io.StringIO(),
                                  TrackerConfig())


def test_many_bad_rows_are_summarised(tmp_path, capsys):
    """Seeded garbage among good rows: the first MAX_REPORTS bad rows are printed one by one, the rest are
    counted by reason in one line; the good rows are tracked as without the garbage."""
    rows, _ = scenario(n_scans=10, n_clutter=2)
    write_csv(tmp_path / 'clean.csv', rows)
    code, _, err = run(capsys, '--input', tmp_path / 'clean.csv', '--output', tmp_path / 'clean_out.csv')
    assert code == 0, err
    rng = np.random.default_rng(14)
    good = (tmp_path / 'clean.csv').read_text().splitlines()
    garbage = [rng.bytes(12).hex()[:int(rng.integers(1, 24))].replace('a', ',') for _ in range(5000)]
    (tmp_path / 'dirty.csv').write_text('\n'.join(good + [g if g.strip(',') else 'x' for g in garbage]) + '\n')
    code, _, err = run(capsys, '--input', tmp_path / 'dirty.csv', '--output', tmp_path / 'dirty_out.csv')
    assert code == 0, err
    lines = err.splitlines()
    shown = [ln for ln in lines if ln.startswith('line ')]
    assert len(shown) == track_csv.MAX_REPORTS and shown[0].startswith(f'line {len(good) + 1}:')
    (summary,) = [ln for ln in lines if ln.startswith('... and ') and 'bad rows' in ln]
    hidden = int(summary.split()[2])
    total = int(lines[-1].split(' bad rows skipped')[0].rsplit(' ', 1)[1])
    assert total == hidden + track_csv.MAX_REPORTS and total > 4000
    assert 'x scan = # is not an integer' in summary
    assert len(lines) < 2 * track_csv.MAX_REPORTS + 10
    # The garbage rows come after the good ones: the tracks are those of the clean file.
    assert (tmp_path / 'dirty_out.csv').read_text() == (tmp_path / 'clean_out.csv').read_text()
