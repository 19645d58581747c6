"""Regenerate every image in docs/images from the documented commands that make it.

Each image comes from a command block of the page that shows it, run as the suite runs it (test/doc_blocks.py:
the page's bash blocks in order, in a scratch folder) or, for a block that is not run in the suite (``make
run``, the 1,000-robot sweep: minutes), that one documented command; the file it writes is copied over the
image. ``--only NAME`` regenerates some images (the sweep's map alone takes tens of minutes).

    python docs/make_figures.py [--only circle_path ...] [--scratch DIR]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'test'))

from doc_blocks import block_environment, blocks, run_document, scratch_root  # noqa: E402

IMAGES = {
    # image: (page, the documented command that makes it, the file it writes, relative to the scratch folder)
    'circle_path': ('README.md', 'wallbot-sim run circle --constraints belt,non_lateral,nonslip --out runs/circle',
                    'runs/circle/plots/path.png'),
    'circle_drive_forces': ('README.md', 'wallbot-sim run circle --constraints belt,non_lateral,nonslip --out runs/circle',
                            'runs/circle/plots/drive_forces.png'),
    'fast_circle_slip_tracking_error': ('docs/examples.md', 'wallbot-sim compare F_ad_400N.csv F_ad_300N.csv',
                                        'slip/tracking_error.png'),
    'fast_circle_slip_friction_use': ('docs/examples.md', 'wallbot-sim plot F_ad_300N.csv --out slip_300/',
                                      'slip_300/friction_use.png'),
    'climb_patch_machine': ('docs/examples.md', 'wallbot-sim plot climb.csv --out climb/', 'climb/machine.png'),
    'sweep_figure8_least_adhesion': ('docs/sweeps.md',
                                     'wallbot-sim sweep examples/sweep_figure8.yaml --out runs/sweep_figure8',
                                     'runs/sweep_figure8/map_least_adhesion_force.png'),
}


def documented_command(page: Path, command: str) -> tuple[bool, int]:
    """Whether ``command`` is in a bash block of ``page`` (else in a block not run, or ``make run``'s words),
    and that block's line; ValueError when the page does not say it."""
    for block in blocks(page):
        if command in block.body:
            return block.runnable, block.line
    if command in page.read_text(encoding='utf-8'):
        return False, 0
    raise ValueError(f'{page.relative_to(ROOT)} no longer documents {command!r}')


def make(name: str, scratch: Path) -> Path:
    page, command, written = IMAGES[name]
    runnable, line = documented_command(ROOT / page, command)
    folder = scratch_root(scratch / Path(page).stem)
    if not (folder / written).exists():
        if runnable:
            failed = [run for run in run_document(ROOT / page, folder, until=line) if run.returncode != 0]
            if failed:
                raise SystemExit(f'{failed[0].block.where} failed:\n{failed[0].output[-3000:]}')
        else:
            subprocess.run(command, shell=True, cwd=folder, env=block_environment(), check=True)
    target = ROOT / 'docs' / 'images' / f'{name}.png'
    shutil.copyfile(folder / written, target)
    return target


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--only', nargs='+', choices=sorted(IMAGES), default=sorted(IMAGES))
    parser.add_argument('--scratch', type=Path, help='where the commands run (default: a temporary folder)')
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as temporary:
        for name in args.only:
            print(make(name, args.scratch or Path(temporary)), flush=True)


if __name__ == '__main__':
    main()
