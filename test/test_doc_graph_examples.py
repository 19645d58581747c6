"""The pages whose command blocks start the node graph (``wallbot-sim run``): run as written (or shortened
where their notes say nothing quoted depends on it), printing what the pages show (test/doc_blocks.py)."""

from __future__ import annotations

from doc_checks import GRAPH_PAGES, DocumentRuns

for _page in GRAPH_PAGES:
    globals()[f'Test_{_page.stem}'] = type(f'Test_{_page.stem}', (DocumentRuns,), {'document': _page})
