"""The headless pages' command blocks run as written, print what the pages show and write what they quote
(test/doc_blocks.py, test/doc_checks.py). ROS-free: the model, plots, motors, a sweep in one process."""

from __future__ import annotations

from doc_blocks import REPO_ROOT
from doc_checks import DocumentRuns


class TestExamples(DocumentRuns):
    document = REPO_ROOT / 'docs' / 'examples.md'


class TestSweeps(DocumentRuns):
    document = REPO_ROOT / 'docs' / 'sweeps.md'


class TestDriving(DocumentRuns):
    document = REPO_ROOT / 'docs' / 'driving.md'


class TestVisualization(DocumentRuns):
    document = REPO_ROOT / 'docs' / 'visualization.md'
