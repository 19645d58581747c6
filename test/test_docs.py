"""The documentation stays true to the repository: links resolve, the CLI reference matches the parsers,
the README stays short, dates stand only beside measured figures, and every fenced block says what it is."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from wallbot_sim.cli.main import build_parser

REPO_ROOT = Path(__file__).resolve().parents[1]
README = REPO_ROOT / 'README.md'
DOCS = sorted((REPO_ROOT / 'docs').glob('*.md'))
DOCUMENTS = [README, *DOCS]
CLI_REFERENCE = REPO_ROOT / 'docs' / 'cli.md'
README_MAX_LINES = 260
"""A newcomer reads the README in five minutes; everything else has a topic file in docs/."""
FENCE_LANGUAGES = {'bash', 'console', 'text', 'yaml', 'xml', 'python'}
"""docs/architecture.md, "The documentation": bash runs as written, console needs more than a shell here."""

FENCE = re.compile(r'^```.*?^```', re.DOTALL | re.MULTILINE)
INLINE_CODE = re.compile(r'`[^`\n]*`')
LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s]+)\)')
HEADING = re.compile(r'^(#{1,6})\s+(.*?)\s*$', re.MULTILINE)
DATE = re.compile(r'\b20\d\d-\d\d-\d\d\b')


def prose(text: str) -> str:
    """The text without fenced blocks and inline code, where a bracket is not a link."""
    return INLINE_CODE.sub('', FENCE.sub('', text))


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation but hyphens and underscores dropped, spaces
    to hyphens."""
    text = heading.replace('`', '').strip().lower()
    text = re.sub(r'[^\w\- ]', '', text)
    return text.replace(' ', '-')


def anchors(path: Path) -> set[str]:
    seen: dict[str, int] = {}
    found = set()
    for _level, heading in HEADING.findall(FENCE.sub('', path.read_text(encoding='utf-8'))):
        base = slug(heading)
        count = seen.get(base, 0)
        found.add(base if count == 0 else f'{base}-{count}')
        seen[base] = count + 1
    return found


def test_every_relative_link_and_image_resolves():
    broken = []
    for document in DOCUMENTS:
        for target in LINK.findall(prose(document.read_text(encoding='utf-8'))):
            if re.match(r'[a-z]+:', target):
                continue  # a web address
            path_part, _, anchor = target.partition('#')
            resolved = (document.parent / path_part).resolve() if path_part else document
            where = f'{document.relative_to(REPO_ROOT)}: {target}'
            if not resolved.exists():
                broken.append(f'{where} (no such file)')
            elif anchor and resolved.suffix == '.md' and anchor not in anchors(resolved):
                broken.append(f'{where} (no such heading)')
    assert not broken, 'broken links:\n' + '\n'.join(broken)


def test_readme_is_short():
    lines = README.read_text(encoding='utf-8').count('\n')
    assert lines <= README_MAX_LINES, f'README.md has {lines} lines: move detail into a topic file of docs/'


def test_dates_stand_only_in_tables_beside_measured_figures():
    dated_prose = []
    for document in DOCUMENTS:
        for number, line in enumerate(document.read_text(encoding='utf-8').splitlines(), 1):
            if DATE.search(line) and not line.lstrip().startswith('|'):
                dated_prose.append(f'{document.relative_to(REPO_ROOT)}:{number}: {line.strip()[:100]}')
    assert not dated_prose, ('dates outside a table of measured figures (docs describe the product as it is; '
                             'figures go in tables with their date):\n' + '\n'.join(dated_prose))


def test_every_fenced_block_names_its_kind():
    unnamed = []
    for document in DOCUMENTS:
        inside = False
        for number, line in enumerate(document.read_text(encoding='utf-8').splitlines(), 1):
            if not line.startswith('```'):
                continue
            if not inside and line[3:].strip() not in FENCE_LANGUAGES:
                unnamed.append(f'{document.relative_to(REPO_ROOT)}:{number}: {line!r}')
            inside = not inside
    assert not unnamed, f'fenced blocks must be one of {sorted(FENCE_LANGUAGES)}:\n' + '\n'.join(unnamed)


# --- docs/cli.md against the argument parsers -----------------------------------------------------

def subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def verb_parsers() -> dict[str, argparse.ArgumentParser]:
    """Every verb's parser by its words ('run', 'bag reindex'): the leaves of the command tree."""
    found = {}
    pending = [((), build_parser())]
    while pending:
        words, parser = pending.pop()
        children = subparsers(parser)
        if words and not children:
            found[' '.join(words)] = parser
        pending += [((*words, name), child) for name, child in children.items()]
    return found


def documented_verbs() -> dict[str, list[str]]:
    """docs/cli.md's sections (``## `wallbot-sim VERB ...```): the verb's words -> the section's lines."""
    sections: dict[str, list[str]] = {}
    current = None
    for line in FENCE.sub('', CLI_REFERENCE.read_text(encoding='utf-8')).splitlines():
        match = re.match(r'## `wallbot-sim ([^`]*)`', line)
        if match:
            words = [word for word in match.group(1).split() if re.fullmatch(r'[a-z]+', word)]
            current = ' '.join(words)
            sections[current] = []
        elif line.startswith('#'):
            current = None
        elif current is not None:
            sections[current].append(line)
    return sections


def option_bullets(lines: list[str]) -> list[tuple[list[str], str]]:
    """Each bullet that documents options: its leading code spans and its whole text."""
    bullets: list[tuple[list[str], str]] = []
    for line in lines:
        match = re.match(r'- ((?:`-[^`]+`(?:, )?)+):', line)
        if match:
            bullets.append((re.findall(r'`([^`]+)`', match.group(1)), line))
        elif bullets and line.startswith('  '):
            bullets[-1] = (bullets[-1][0], bullets[-1][1] + ' ' + line.strip())
        elif not line.startswith('  '):
            bullets.append(([], ''))  # a paragraph ends the bullet before it
    return [bullet for bullet in bullets if bullet[0]]


def same_value(written: str, value: object) -> bool:
    if isinstance(value, bool) or value is None:
        return written == str(value)
    if isinstance(value, (int, float)):
        try:
            return float(written) == float(value)
        except ValueError:
            return False
    return written == str(value)


def test_every_verb_has_a_section_of_the_cli_reference():
    assert sorted(documented_verbs()) == sorted(verb_parsers())


@pytest.mark.parametrize('verb', sorted(verb_parsers()))
def test_the_cli_reference_lists_exactly_the_options_of_each_verb(verb: str):
    parser = verb_parsers()[verb]
    actions = {option: action for action in parser._actions for option in action.option_strings
               if option not in ('-h', '--help')}
    documented, problems = set(), []
    for spans, text in option_bullets(documented_verbs().get(verb, [])):
        bullet_actions = []
        for span in spans:
            option, *rest = span.split()
            documented.add(option)
            action = actions.get(option)
            if action is None:
                problems.append(f'{option}: documented, but the parser has no such option')
                continue
            bullet_actions.append(action)
            if rest and '|' in rest[0] and set(rest[0].split('|')) != set(action.choices or ()):
                problems.append(f'{option}: documented choices {rest[0]}, the parser has {action.choices}')
        for written in re.findall(r'default `([^`]+)`', text):
            for action in bullet_actions:
                if not same_value(written, action.default):
                    problems.append(f'{action.option_strings[0]}: documented default {written!r}, the parser has '
                                    f'{action.default!r}')
    missing = sorted(set(actions) - documented)
    problems += [f'{option}: an option of the parser, not in docs/cli.md' for option in missing]
    assert not problems, f'docs/cli.md, wallbot-sim {verb}:\n' + '\n'.join(problems)


def test_the_cli_reference_lists_the_csv_columns_in_order():
    from wallbot_sim.rundata.csv_format import CSV_COLUMNS
    text = FENCE.sub('', CLI_REFERENCE.read_text(encoding='utf-8'))
    assert f"`{','.join(CSV_COLUMNS)}`" in text[text.index('### The CSV'):], 'docs/cli.md: the CSV columns differ'


# --- the command blocks: each runs in the suite or says why not (test/doc_blocks.py) -------------------

def test_every_command_block_runs_in_the_suite_or_says_why_not():
    from doc_blocks import DOCUMENTS as PAGES, NOT_RUN, SHORTENED, blocks
    problems = []
    for page in PAGES:
        for block in blocks(page):
            if block.kind == 'console' and block.not_run_reason is None:
                problems.append(f'{block.where}: a console block without "<!-- not run: REASON -->" before it')
            elif block.kind == 'bash' and block.note and not SHORTENED.fullmatch(block.note):
                problems.append(f'{block.where}: a bash block runs; its note {block.note!r} is no shortening')
            elif block.kind == 'bash':
                try:
                    block.script()
                except ValueError as error:
                    problems.append(str(error))
            elif block.kind not in ('bash', 'console') and NOT_RUN.fullmatch(block.note):
                problems.append(f'{block.where}: a {block.kind} block is no command')
    assert not problems, '\n'.join(problems)


def test_every_page_with_commands_is_run_by_a_test_class():
    from doc_blocks import DOCUMENTS as PAGES, blocks
    from doc_checks import GRAPH_PAGES, HEADLESS_PAGES
    with_commands = {page for page in PAGES if any(block.runnable for block in blocks(page))}
    assert with_commands == set(GRAPH_PAGES) | set(HEADLESS_PAGES) and not set(GRAPH_PAGES) & set(HEADLESS_PAGES)


def test_every_quoted_number_checked_is_still_quoted():
    from doc_checks import CLAIMS
    for claim in CLAIMS:
        assert all(claim.quoted()), claim.pattern


def test_every_image_of_the_docs_is_made_by_docs_make_figures():
    import importlib.util
    spec = importlib.util.spec_from_file_location('make_figures', REPO_ROOT / 'docs' / 'make_figures.py')
    make_figures = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_figures)
    shown = {Path(target).stem for document in DOCUMENTS for target in LINK.findall(prose(document.read_text(encoding='utf-8')))
             if target.endswith('.png')}
    assert shown == set(make_figures.IMAGES) == {path.stem for path in (REPO_ROOT / 'docs' / 'images').glob('*.png')}
    for page, command, _written in make_figures.IMAGES.values():
        make_figures.documented_command(REPO_ROOT / page, command)
