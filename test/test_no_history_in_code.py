"""Comments and docstrings under sonar_tracking/ say what the code does, not its history.

Dated entries live in docs/experiments/ and are linked from code (a link such as
``docs/experiments/2026-11-21-fls-gpf-study.md`` is allowed); a diary in a docstring is not.
"""
from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

NARRATION = re.compile(r"""(?ix)
    \b(?:today|tonight|yesterday|this\ (?:morning|afternoon|evening)|last\ night)\b
  | \b(?:previous|last|earlier|this|that)\ session\b
  | \bquiet\ machine\b | \bfresh\ checkout\b | \bmain\ of\ (?:that|this)\b
  | \bwe\ (?:tried|measured|switched|reverted)\b
  | \b(?:was|were)\ ~?[\d.]+\ ?(?:ms|us|s)\b[^.]*\bnow\b
  | \b(?:before|after|since)\ (?:this|that)\ (?:change|commit|fix|session)\b
  | (?<!experiments/)\b20\d\d-\d\d-\d\d\b(?!-[a-z])
""")


def prose(source: str) -> list[tuple[int, str]]:
    """``(line, text)`` of every comment and docstring in ``source``."""
    out = [(tok.start[0], tok.string) for tok in tokenize.generate_tokens(io.StringIO(source).readline)
           if tok.type == tokenize.COMMENT]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=False)
            if doc is not None:
                out.append((node.body[0].lineno, doc))
    return out


def narration(path: Path, root: Path = ROOT) -> list[str]:
    found = []
    for line, text in prose(path.read_text()):
        for m in NARRATION.finditer(text.replace('\n', ' ')):
            found.append(f'{path.relative_to(root)}:{line}: {m.group(0)!r}')
    return found


def test_no_comment_or_docstring_narrates_history():
    found = [hit for path in sorted((ROOT / 'sonar_tracking').rglob('*.py')) for hit in narration(path)]
    assert found == [], 'move dated history to docs/experiments/ and link it:\n' + '\n'.join(found)


def test_the_guard_sees_narration_and_lets_links_pass(tmp_path):
    bad = tmp_path / 'bad.py'
    bad.write_text('"""Faster since this change: the step was 21 ms, now 14 ms (quiet machine, 2026-11-26)."""\n'
                   '# measured this morning\nx = 1\n')
    good = tmp_path / 'good.py'
    good.write_text('"""Why: see docs/experiments/2026-11-21-fls-gpf-study.md."""\n'
                    '# the date is read at run time\nimport datetime\nd = datetime.date.today()\n')
    hits = narration(bad, tmp_path)
    assert len(hits) == 5, hits
    assert narration(good, tmp_path) == []
