"""Every relative link of README.md and docs/ points to an existing file (and an anchor into a
Markdown file to one of its headings), so the guide survives files moving between folders."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s]+)(?:\s+"[^"]*")?\)')
FENCE = re.compile(r'```.*?```', re.S)


def headings(md: Path) -> set[str]:
    """GitHub's anchors of a Markdown file's headings."""
    text = FENCE.sub('', md.read_text())
    return {re.sub(r'[^\w\- ]', '', m.group(1).strip().lower()).replace(' ', '-')
            for m in re.finditer(r'^#{1,6}\s+(.*)$', text, re.M)}


def broken_links(files: list[Path], root: Path = ROOT) -> list[str]:
    bad = []
    for md in files:
        for target in LINK.findall(FENCE.sub('', md.read_text())):
            if re.match(r'^[a-z]+:', target) or target.startswith('#'):
                continue
            path, _, anchor = target.partition('#')
            dest = (md.parent / path).resolve()
            if not dest.exists():
                bad.append(f'{md.relative_to(root)}: {target} does not exist')
            elif anchor and dest.suffix == '.md' and anchor not in headings(dest):
                bad.append(f'{md.relative_to(root)}: {target} names no heading of {path}')
    return bad


def test_every_relative_link_resolves():
    files = [ROOT / 'README.md', *sorted((ROOT / 'docs').rglob('*.md'))]
    assert broken_links(files) == []


def test_a_broken_link_and_anchor_are_reported(tmp_path):
    (tmp_path / 'a.md').write_text('# Top\n\n## Part two\n')
    page = tmp_path / 'b.md'
    page.write_text('[ok](a.md#part-two) [gone](c.md) [bad](a.md#part-three)\n```\n[in code](x.md)\n```\n')
    assert broken_links([page], tmp_path) == ['b.md: c.md does not exist',
                                              'b.md: a.md#part-three names no heading of a.md']
