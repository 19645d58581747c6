"""The headless pages' command blocks run as written, print what the pages show and write what they quote
(test/doc_blocks.py, test/doc_checks.py). ROS-free: the model, plots, motors, a sweep in one process. A class a
page, so that the pages spread over the workers (each class, whose tests share its page's run, one xdist group)."""

from __future__ import annotations

from doc_checks import HEADLESS_PAGES, DocumentRuns

for _page in HEADLESS_PAGES:
    globals()[f'Test_{_page.stem}'] = type(f'Test_{_page.stem}', (DocumentRuns,), {'document': _page})
