"""The repository is self-contained: no file points to a file outside it."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
# Spelled in pieces so that this file does not match itself.
FORBIDDEN = ('MODEL' + '.md', '../' + 'shared', '/work/' + 'shared')
MARKDOWN_LINK = re.compile(r'\]\(([^)\s]+)\)')
SKIPPED_DIRS = {'.git', '.venv', 'build', 'install', 'log', 'runs', '__pycache__', '.pytest_cache'}


def tracked_files() -> list[Path]:
    """The files git tracks, or every file of the tree when this is not a git checkout."""
    listing = subprocess.run(['git', 'ls-files', '-z'], cwd=REPO_ROOT, capture_output=True)
    if listing.returncode == 0 and listing.stdout:
        return [REPO_ROOT / name for name in listing.stdout.decode().split('\0') if name]
    return [path for path in REPO_ROOT.rglob('*')
            if path.is_file() and not SKIPPED_DIRS.intersection(path.relative_to(REPO_ROOT).parts)
            and '.egg-info' not in str(path)]


def text_of(path: Path) -> str | None:
    try:
        return path.read_text(encoding='utf-8')
    except (UnicodeDecodeError, FileNotFoundError):
        return None  # binary (images) or deleted in the work tree


def test_no_file_cites_a_document_outside_the_repository():
    offenders = []
    for path in tracked_files():
        text = text_of(path)
        if text is None:
            continue
        for number, line in enumerate(text.splitlines(), 1):
            offenders += [f'{path.relative_to(REPO_ROOT)}:{number}: {word}' for word in FORBIDDEN if word in line]
    assert not offenders, 'references to files outside the repository:\n' + '\n'.join(offenders)


def test_markdown_links_stay_inside_the_repository():
    broken = []
    markdown = [path for path in tracked_files() if path.suffix == '.md']
    assert REPO_ROOT / 'docs' / 'model.md' in markdown
    for path in markdown:
        text = text_of(path) or ''
        for target in MARKDOWN_LINK.findall(text):
            if re.match(r'[a-z]+:', target) or target.startswith('#'):
                continue  # a web address or an anchor on the same page
            resolved = (path.parent / target.split('#')[0]).resolve()
            if not resolved.is_relative_to(REPO_ROOT):
                broken.append(f'{path.relative_to(REPO_ROOT)}: {target}')
    assert not broken, 'links that leave the repository:\n' + '\n'.join(broken)
