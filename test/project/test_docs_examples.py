"""Every ```python block in README.md and docs/**/*.md runs, from the repository root.

The blocks of one file run in order in one namespace (a page's later block may use an earlier
one's names), each compiled with its file and line so a failure points at the block.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FENCE = re.compile(r'^(?P<indent> *)(?P<fence>```+|~~~+)\s*(?P<info>[^\n`]*)$')
SKIP_PARTS = {'_build', '_generated'}


def markdown_files() -> list[Path]:
    """Return README.md and every Markdown page under docs/ (build output left out)."""
    pages = [p for p in sorted((ROOT / 'docs').rglob('*.md'))
             if not SKIP_PARTS & set(p.relative_to(ROOT).parts)]
    return [ROOT / 'README.md', *pages]


def python_blocks(text: str) -> list[tuple[int, str]]:
    """Return (first line number, source) of each ```python fenced block of Markdown ``text``."""
    blocks: list[tuple[int, str]] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        opening = FENCE.match(lines[i])
        if opening is None:
            i += 1
            continue
        fence, indent = opening['fence'], len(opening['indent'])
        info = opening['info'].strip()
        body: list[str] = []
        i += 1
        while i < len(lines) and not re.match(rf'^ *{re.escape(fence)}\s*$', lines[i]):
            body.append(lines[i][indent:] if lines[i][:indent].strip() == '' else lines[i])
            i += 1
        start = i - len(body) + 1  # 1-based line of the block's first source line
        if info.split() and info.split()[0] in ('python', 'py', '{code-block}', '{code}') and (
                info.split()[0] in ('python', 'py') or info.split()[1:2] == ['python']):
            blocks.append((start, '\n'.join(line for line in body
                                            if not line.startswith(':'))))
        i += 1
    return blocks


def test_blocks_are_found() -> None:
    """The extractor sees blocks, their lines and both fence styles (a control for the test)."""
    text = 'x\n```python\na = 1\n```\n\n~~~ python\nb = 2\n~~~\n```bash\nls\n```\n'
    assert python_blocks(text) == [(3, 'a = 1'), (7, 'b = 2')]
    assert python_blocks('```{code-block} python\nc = 3\n```\n') == [(2, 'c = 3')]


def test_readme_has_examples() -> None:
    """The README's quick starts are Python blocks, so this test runs them."""
    assert len(python_blocks((ROOT / 'README.md').read_text(encoding='utf-8'))) >= 2


@pytest.mark.parametrize('path', markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_python_blocks_run(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Run each Python block of ``path`` in order, from the repository root."""
    monkeypatch.chdir(ROOT)
    namespace: dict[str, object] = {'__name__': '__docs__'}
    rel = path.relative_to(ROOT)
    for line, source in python_blocks(path.read_text(encoding='utf-8')):
        padded = '\n' * (line - 1) + source  # tracebacks name the Markdown line
        try:
            exec(compile(padded, str(rel), 'exec'), namespace)
        except Exception as exc:
            pytest.fail(f'{rel}:{line}: the block starting here raised '
                        f'{type(exc).__name__}: {exc}')


def test_readme_links_point_at_files() -> None:
    """Every relative link and picture of the README names a file or folder in the tree."""
    text = (ROOT / 'README.md').read_text(encoding='utf-8')
    targets = re.findall(r'\]\(([^)#\s]+)\)', text)
    assert len(targets) >= 10
    missing = [t for t in targets if '://' not in t and not (ROOT / t).exists()]
    assert missing == []
