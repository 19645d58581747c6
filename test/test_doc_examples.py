"""The headless pages' command blocks run as written, print what the pages show and write what they quote
(test/doc_blocks.py, test/doc_checks.py). ROS-free: the model, plots, motors, a sweep in one process. A class a
page, so that xdist's loadscope spreads the pages over the workers."""

from __future__ import annotations

from doc_checks import HEADLESS_PAGES, DocumentRuns

for _page in HEADLESS_PAGES:
    globals()[f'Test_{_page.stem}'] = type(f'Test_{_page.stem}', (DocumentRuns,), {'document': _page})
