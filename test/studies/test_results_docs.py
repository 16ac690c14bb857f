"""The docs/results tables are those the studies' format_table makes of the committed full-run JSON,
and that JSON holds the evidence the tables claim (out-of-sample seeds, T_c read back, replication)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from sonar_tracking.studies.results_docs import BEGIN, END, TABLES, render, stale

RESULTS = Path(__file__).resolve().parents[2] / 'docs' / 'results'


def test_every_generated_table_is_that_of_its_committed_json():
    assert stale(RESULTS) == [], ('regenerate: python -c "from sonar_tracking.studies.results_docs import '
                                  'regenerate; regenerate(\'docs/results\')"')


def test_render_replaces_only_the_generated_block():
    begin, end = BEGIN.format(json='t.json', module='m'), END.format(json='t.json')
    page = f'intro\n{begin}\n\nold table\n\n{end}\noutro\n'
    assert render(page, 't.json', 'm', '| new |') == f'intro\n{begin}\n\n| new |\n\n{end}\noutro\n'
    with pytest.raises(ValueError, match='marker'):
        render('no markers', 't.json', 'm', '| new |')


def _json(name: str) -> dict:
    return json.loads((RESULTS / name).read_text())


@pytest.mark.parametrize('name', sorted({t[1] for t in TABLES}))
def test_committed_full_runs_are_out_of_sample_and_replicated(name):
    r = _json(name)
    seeds = r['seeds']
    assert len(seeds['evaluation']) >= 2 and not set(seeds['calibration']) & set(seeds['evaluation'])
    assert not set(seeds['tuned_on']) & set(seeds['evaluation'])
    assert r['correction']['method'] == 'bonferroni' and set(r['gospa']) == {'c', 'p', 'alpha'}
    groups = r.get('studies') or r.get('situations') or r.get('cells')
    for g in groups:
        for c in g['comparisons']:
            runs = [c['seeds'][str(s)]['runs'] for s in seeds['evaluation']]
            assert len(set(runs)) == 1 and c['pooled']['runs'] == sum(runs)   # the same runs per seed set
            assert c['agree'] in (True, False)


def test_committed_tables_ran_every_tracker_at_its_chosen_operating_point():
    """Acceptance: per method, the T_c (the GPF: confirm_hits) read back from each evaluation run's tracker
    equals the one chosen on the calibration seeds."""
    for s in _json('esc_table.json')['studies']:
        for m in s['methods'].values():
            assert m['t_c_read_back']['read_back'] == [m['calibration']['t_c']] and m['t_c_read_back']['equal']
    for name in ('fls_table_crossings.json', 'fls_table_single.json'):
        for s in _json(name)['situations']:
            for m in s['methods'].values():
                rb = m['confirm_hits_read_back']
                assert rb['read_back'] == [m['calibration']['confirm_hits']] and rb['equal']
    for c in _json('jipda_table.json')['cells']:
        for m in c['methods'].values():
            assert m['t_c_read_back']['read_back'] == [m['calibration']['t_c']] and m['t_c_read_back']['equal']
