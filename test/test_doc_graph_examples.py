"""The pages whose command blocks start the node graph (``wallbot-sim run``): run as written (or shortened
where their notes say nothing quoted depends on it), printing what the pages show (test/doc_blocks.py)."""

from __future__ import annotations

from doc_blocks import REPO_ROOT
from doc_checks import DocumentRuns


class TestReadme(DocumentRuns):
    document = REPO_ROOT / 'README.md'


class TestController(DocumentRuns):
    document = REPO_ROOT / 'docs' / 'controller.md'
