"""A bench script's figures as Markdown tables in docs/performance.md (shared by the bench scripts).

Each script makes one ``Report`` when it starts (the date and the load average then), adds its tables
as it measures, and with ``--write-docs`` replaces its own section of docs/performance.md, the text
between ``<!-- bench:NAME -->`` and ``<!-- /bench:NAME -->``, with them. The section opens with the
conditions of the measurement: the command, the machine (CPU model from /proc/cpuinfo, cores), the
date, the 1-minute load average at the start and at the end, and the versions that matter; the tables
follow, each with the ratios against the baseline the script measures in the same process. A section
the file does not have yet is appended at its end.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import shlex
import sys
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Sequence

DOCS = Path(__file__).resolve().parents[1] / 'docs' / 'performance.md'
"""The document the sections are written into."""
WRITE_DOCS_OPTION = '--write-docs'


def add_write_docs_option(parser: argparse.ArgumentParser) -> None:
    """``--write-docs [FILE]``: write the script's section into FILE (default docs/performance.md)."""
    parser.add_argument(WRITE_DOCS_OPTION, nargs='?', const=str(DOCS), default=None, metavar='FILE',
                        help='also write the figures as tables into their section of FILE (default '
                             'docs/performance.md)')


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo (the platform's processor string elsewhere)."""
    try:
        for line in Path('/proc/cpuinfo').read_text(encoding='utf-8').splitlines():
            if line.startswith('model name'):
                return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def versions() -> str:
    """Python and, where this process imported them, numpy and numba."""
    found = [f'Python {platform.python_version()}']
    for name in ('numpy', 'numba'):
        module = sys.modules.get(name)
        if module is not None:
            found.append(f'{name} {module.__version__}')
    return ', '.join(found)


def cell(value: object) -> str:
    """A table cell: floats as given by the caller (already formatted), pipes escaped."""
    return str(value).replace('|', '\\|')


@dataclass
class Table:
    """One Markdown table: an optional title line above it, the header and the rows."""

    header: Sequence[str]
    rows: list[Sequence[object]]
    title: str = ''

    def markdown(self) -> str:
        lines = [f'{self.title}\n'] if self.title else []
        lines.append('| ' + ' | '.join(cell(name) for name in self.header) + ' |')
        lines.append('|' + '---|' * len(self.header))
        lines += ['| ' + ' | '.join(cell(value) for value in row) + ' |' for row in self.rows]
        return '\n'.join(lines)


@dataclass
class Report:
    """The figures of one bench run, for its section ``name`` of docs/performance.md."""

    name: str
    argv: Sequence[str] = field(default_factory=lambda: list(sys.argv))
    tables: list[Table] = field(default_factory=list)
    started: datetime = field(default_factory=lambda: datetime.now(timezone.utc))
    load_at_start: float = field(default_factory=lambda: os.getloadavg()[0])

    def table(self, header: Sequence[str], rows: list[Sequence[object]], title: str = '') -> None:
        """Add a table to the section."""
        self.tables.append(Table(header, rows, title))

    def command(self) -> str:
        """The command as run, without ``--write-docs`` and its file."""
        script, *args = self.argv
        kept: list[str] = []
        after_option = False
        for arg in args:
            if after_option and not arg.startswith('-'):
                after_option = False  # the option's FILE
                continue
            after_option = arg == WRITE_DOCS_OPTION
            if not after_option and not arg.startswith(WRITE_DOCS_OPTION + '='):
                kept.append(arg)
        return shlex.join(['python', f'bench/{Path(script).name}', *kept])

    def markdown(self) -> str:
        """The section's text: the conditions, then the tables."""
        conditions = Table(('command', 'machine', 'date (UTC)', 'load average (1 min) at start / end', 'software'), [(
            f'`{self.command()}`', f'{cpu_model()}, {os.cpu_count()} cores', f'{self.started:%Y-%m-%d %H:%M}',
            f'{self.load_at_start:.2f} / {os.getloadavg()[0]:.2f}', versions())])
        return '\n\n'.join(table.markdown() for table in (conditions, *self.tables))

    def write(self, path: str | Path | None) -> None:
        """Replace the section in ``path`` (nothing when ``path`` is None, i.e. no ``--write-docs``)."""
        if path is None:
            return
        path = Path(path)
        text = path.read_text(encoding='utf-8')
        updated = replace_section(text, self.name, self.markdown())
        path.write_text(updated, encoding='utf-8')
        print(f'wrote section bench:{self.name} of {path}')


def section_pattern(name: str) -> re.Pattern[str]:
    return re.compile(rf'(^<!-- bench:{re.escape(name)} -->\n).*?(\n<!-- /bench:{re.escape(name)} -->$)',
                      re.DOTALL | re.MULTILINE)


def replace_section(text: str, name: str, body: str) -> str:
    """``text`` with the section ``name`` holding ``body``; appended at the end when it has none."""
    pattern = section_pattern(name)
    if pattern.search(text) is None:
        return text.rstrip('\n') + f'\n\n<!-- bench:{name} -->\n{body}\n<!-- /bench:{name} -->\n'
    return pattern.sub(lambda match: match.group(1) + body + match.group(2), text, count=1)
