"""The tables of ``docs/results`` generated from the committed full-run JSON of each study.

Every generated table sits in its page between two marker lines naming its JSON file
(:data:`BEGIN`, :data:`END`); :func:`regenerate` replaces what lies between them with the study's
``format_table`` of that JSON, and :func:`stale` lists the tables that differ from it (the test
``test/studies/test_results_docs.py`` fails on any). After a new full run::

    python -c "from sonar_tracking.studies.results_docs import regenerate; regenerate('docs/results')"
"""
from __future__ import annotations

import importlib
import json
from pathlib import Path

__all__ = ['TABLES', 'BEGIN', 'END', 'table_text', 'render', 'regenerate', 'stale']

#: (page, full-run JSON, module whose ``format_table`` makes the table), all in ``docs/results``.
TABLES = (
    ('esc_paper.md', 'esc_table.json', 'sonar_tracking.studies.esc_table'),
    ('fls_gpf.md', 'fls_table_crossings.json', 'sonar_tracking.studies.fls_table'),
    ('fls_gpf.md', 'fls_table_single.json', 'sonar_tracking.studies.fls_table'),
    ('jipda.md', 'jipda_table.json', 'sonar_tracking.studies.jipda_table'),
    ('imaging.md', 'imaging_table.json', 'sonar_tracking.studies.imaging_table'),
)

BEGIN = '<!-- generated from {json} by {module}.format_table; do not edit by hand -->'
END = '<!-- end of the table generated from {json} -->'


def table_text(results: Path, json_name: str, module: str) -> str:
    """The table ``module.format_table`` makes of ``results/json_name``."""
    data = json.loads((Path(results) / json_name).read_text())
    return importlib.import_module(module).format_table(data)


def render(page: str, json_name: str, module: str, table: str) -> str:
    """``page`` with the block between the markers of ``json_name`` replaced by ``table``; ValueError
    when the page lacks either marker or has them twice."""
    begin, end = BEGIN.format(json=json_name, module=module), END.format(json=json_name)
    if page.count(begin) != 1 or page.count(end) != 1:
        raise ValueError(f'the page needs the marker lines once each:\n{begin}\n{end}')
    head, rest = page.split(begin, 1)
    _, tail = rest.split(end, 1)
    return f'{head}{begin}\n\n{table}\n\n{end}{tail}'


def regenerate(results: str | Path) -> list[str]:
    """Rewrite every generated table of the pages in ``results``; returns the pages changed."""
    results = Path(results)
    changed = []
    for page, json_name, module in TABLES:
        path = results / page
        old = path.read_text()
        new = render(old, json_name, module, table_text(results, json_name, module))
        if new != old:
            path.write_text(new)
            changed.append(page)
    return changed


def stale(results: str | Path) -> list[str]:
    """``page: json`` of every generated table whose text differs from its JSON's table."""
    results = Path(results)
    out = []
    for page, json_name, module in TABLES:
        text = (results / page).read_text()
        if render(text, json_name, module, table_text(results, json_name, module)) != text:
            out.append(f'{page}: {json_name}')
    return out
