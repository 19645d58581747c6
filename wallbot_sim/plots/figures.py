"""The paper's figures as PNG (matplotlib, Agg backend), for one run or several overlaid.

| file | paper figures |
|---|---|
| path.png | 6, 14, 22: reference vs actual path of the centre |
| position.png | 4, 20: x(t), y(t) against the reference |
| tracking_error.png | 7, 15, 23 |
| attitude.png | 5, 10, 13, 21: attitude angle theta(t) |
| wheel_tracks.png | 8, 11, 16, 24: tracks of the four wheel axle centres |
| constraint_forces.png | 9, 12, 17, 25: F_X, F_Y and M_Z |
| drive_forces.png | 18, 19, 26, 27: left and right drive (traction) forces, and the lateral force |
| normal_loads.png | (wheel-wall contact) normal load of each wheel; below 0 a wheel lifts off |
| friction_use.png | (wheel-wall contact) friction use of each wheel against the limit 1, its slides shaded |
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from wallbot_msgs_py import topics
from wallbot_sim.plots.errors import PlotError
from wallbot_sim.rundata import RunData

FIGURES = ('path', 'position', 'tracking_error', 'attitude', 'wheel_tracks', 'constraint_forces', 'drive_forces',
           'normal_loads', 'friction_use')
"""Base names of the PNG files written, in this order."""

WHEEL_OFFSETS = {  # body-frame axle centres in units of (a, b): x forward, y to the left
    'wheel_left_front': (1, 1), 'wheel_left_rear': (-1, 1),
    'wheel_right_front': (1, -1), 'wheel_right_rear': (-1, -1)}


def wheel_tracks(run: RunData, half_wheelbase: float, half_track: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Wall-frame axle-centre positions of each wheel: centre + R(theta) (+-a, +-b)."""
    c, s = np.cos(run.theta), np.sin(run.theta)
    tracks = {}
    for name in topics.WHEEL_JOINTS:
        fx, fy = WHEEL_OFFSETS[name]
        bx, by = fx * half_wheelbase, fy * half_track
        tracks[name] = (run.x + c * bx - s * by, run.y + s * bx + c * by)
    return tracks


def _prepare_out(out_dir: Path) -> Path:
    out_dir = Path(out_dir)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise PlotError(f'cannot create output directory {out_dir}: {error.strerror}') from None
    if not out_dir.is_dir() or not os.access(out_dir, os.W_OK | os.X_OK):
        raise PlotError(f'output directory {out_dir} is not writable')
    return out_dir


def write_figures(runs: Sequence[RunData], out_dir: Path | str, half_wheelbase: float | None = None,
                  half_track: float | None = None) -> list[Path]:
    """Write the figure set for ``runs`` (overlaid when several) into ``out_dir``; return the files."""
    if half_wheelbase is None or half_track is None:
        from wallbot_sim.config import load_robot_parameters
        params = load_robot_parameters()
        half_wheelbase = params.half_wheelbase if half_wheelbase is None else half_wheelbase
        half_track = params.half_track if half_track is None else half_track
    figures = _Figures(runs, _prepare_out(Path(out_dir)))
    figures.path()
    figures.position()
    figures.tracking_error()
    figures.attitude()
    figures.wheel_tracks(half_wheelbase, half_track)
    figures.constraint_forces()
    figures.drive_forces()
    figures.normal_loads()
    figures.friction_use()
    return figures.written


class _Figures:
    """The figures of ``runs`` (overlaid when several), each written into ``out`` by one method, in FIGURES' order."""

    def __init__(self, runs: Sequence[RunData], out: Path) -> None:
        import matplotlib
        matplotlib.use('Agg', force=True)
        import matplotlib.pyplot as plt
        self.plt, self.runs, self.out = plt, runs, out
        self.first, self.many = runs[0], len(runs) > 1
        self.title_suffix = '' if self.many else f' ({runs[0].label})'
        self.written: list[Path] = []

    def label(self, run: RunData, what: str = '') -> str:
        return f'{run.label}{": " + what if what else ""}' if self.many else (what or run.label)

    def save(self, fig, name: str) -> None:
        fig.tight_layout()
        target = self.out / f'{name}.png'
        try:
            fig.savefig(target, dpi=110)
        except OSError as error:
            raise PlotError(f'cannot write {target}: {error.strerror}') from None
        finally:
            self.plt.close(fig)
        self.written.append(target)

    def _over_time(self, name: str, values: Callable[[RunData], np.ndarray], ylabel: str, title: str,
                   what: str) -> None:
        """One quantity of every run (``values`` of it) against time."""
        fig, ax = self.plt.subplots(figsize=(7.5, 4.5))
        for run in self.runs:
            ax.plot(run.t, values(run), lw=1.3, label=self.label(run, what))
        ax.set(xlabel='time (s)', ylabel=ylabel, title=title + self.title_suffix)
        ax.grid(True, alpha=0.3)
        ax.legend(loc='best', fontsize='small')
        self.save(fig, name)

    def path(self) -> None:
        first = self.first
        fig, ax = self.plt.subplots(figsize=(6.4, 6.0))
        if len(first.path_x):
            ax.plot(first.path_x, first.path_y, 'k--', lw=1.2, label='reference path')
        else:
            ax.plot(first.ref_x, first.ref_y, 'k--', lw=1.2, label='reference path')
        for run in self.runs:
            ax.plot(run.x, run.y, lw=1.4, label=self.label(run, 'actual path'))
        ax.plot(first.x[:1], first.y[:1], 'o', color='tab:green', label='start')
        ax.set(xlabel='x (m)', ylabel='y (m)', title='Path of the centre: reference vs actual' + self.title_suffix)
        ax.set_aspect('equal', adjustable='datalim')
        ax.grid(True, alpha=0.3)
        ax.legend(loc='best', fontsize='small')
        self.save(fig, 'path')

    def position(self) -> None:
        fig, axes = self.plt.subplots(2, 1, sharex=True, figsize=(7.5, 6.0))
        for ax, coord, refc, name in ((axes[0], 'x', 'ref_x', 'x'), (axes[1], 'y', 'ref_y', 'y')):
            ax.plot(self.first.t, getattr(self.first, refc), 'k--', lw=1.2, label=f'reference {name}_d(t)')
            for run in self.runs:
                ax.plot(run.t, getattr(run, coord), lw=1.3, label=self.label(run, f'actual {name}(t)'))
            ax.set(ylabel=f'{name} (m)')
            ax.grid(True, alpha=0.3)
            ax.legend(loc='best', fontsize='small')
        axes[0].set_title('Position of the centre against the reference' + self.title_suffix)
        axes[1].set_xlabel('time (s)')
        self.save(fig, 'position')

    def tracking_error(self) -> None:
        self._over_time('tracking_error', lambda run: run.err, 'tracking error |p - p_d| (m)', 'Tracking error',
                        'tracking error')

    def attitude(self) -> None:
        self._over_time('attitude', lambda run: np.unwrap(run.theta), 'attitude angle theta (rad)', 'Attitude angle',
                        'attitude angle theta')

    def wheel_tracks(self, half_wheelbase: float, half_track: float) -> None:
        fig, ax = self.plt.subplots(figsize=(6.4, 6.0))
        styles = ('-', '--', '-.', ':')
        for k, run in enumerate(self.runs):
            for name, (wx, wy) in wheel_tracks(run, half_wheelbase, half_track).items():
                pretty = name.replace('wheel_', '').replace('_', ' ')
                ax.plot(wx, wy, styles[k % len(styles)], lw=1.0, label=self.label(run, f'{pretty} wheel'))
        ax.set(xlabel='x (m)', ylabel='y (m)', title='Tracks of the four wheels' + self.title_suffix)
        ax.set_aspect('equal', adjustable='datalim')
        ax.grid(True, alpha=0.3)
        ax.legend(loc='best', fontsize='x-small', ncol=2 if self.many else 1)
        self.save(fig, 'wheel_tracks')

    def constraint_forces(self) -> None:
        fig, axes = self.plt.subplots(2, 1, sharex=True, figsize=(7.5, 6.0))
        for run in self.runs:
            axes[0].plot(run.t, run.Fx, lw=1.2, label=self.label(run, 'F_X'))
            axes[0].plot(run.t, run.Fy, lw=1.2, label=self.label(run, 'F_Y'))
            axes[1].plot(run.t, run.Mz, lw=1.2, label=self.label(run, 'M_Z'))
        axes[0].set(ylabel='constraint force (N)',
                    title='Constraint forces and torque on the chassis' + self.title_suffix)
        axes[1].set(xlabel='time (s)', ylabel='constraint torque M_Z (N m)')
        for ax in axes:
            ax.grid(True, alpha=0.3)
            ax.legend(loc='best', fontsize='small')
        self.save(fig, 'constraint_forces')

    def drive_forces(self) -> None:
        fig, axes = self.plt.subplots(3, 1, sharex=True, figsize=(7.5, 7.5))
        for run in self.runs:
            axes[0].plot(run.t, run.F_left, lw=1.2, label=self.label(run, 'left drive force F_L'))
            axes[1].plot(run.t, run.F_right, lw=1.2, label=self.label(run, 'right drive force F_R'))
            axes[2].plot(run.t, run.F_lateral, lw=1.2, label=self.label(run, 'lateral force F_lat'))
        axes[0].set(ylabel='F_L (N)', title='Drive forces' + self.title_suffix)
        axes[1].set(ylabel='F_R (N)')
        axes[2].set(xlabel='time (s)', ylabel='F_lat (N)')
        for ax in axes:
            ax.grid(True, alpha=0.3)
            ax.legend(loc='best', fontsize='small')
        self.save(fig, 'drive_forces')

    def normal_loads(self) -> None:
        fig, ax = self.plt.subplots(figsize=(7.5, 4.5))
        for run in self.runs:
            for i, name in enumerate(topics.WHEEL_JOINTS):
                if len(run.loads):
                    ax.plot(run.t, run.loads[:, i], lw=1.2,
                            label=self.label(run, name.replace('wheel_', '').replace('_', ' ')))
        ax.axhline(0.0, color='k', lw=0.8)
        ax.set(xlabel='time (s)', ylabel='normal load N_i (N)',
               title='Normal loads of the wheels (below 0: lifts off)' + self.title_suffix)
        _note_missing(ax, self.runs)
        self.save(fig, 'normal_loads')

    def friction_use(self) -> None:
        fig, axes = self.plt.subplots(2, 2, sharex=True, sharey=True, figsize=(9.0, 6.5))
        for wheel, ax in zip(range(4), (axes[0, 0], axes[1, 0], axes[0, 1], axes[1, 1])):  # front row, left column
            name = topics.WHEEL_JOINTS[wheel].replace('wheel_', '').replace('_', ' ')
            for run in self.runs:
                if len(run.use):
                    line, = ax.plot(run.t, run.use[:, wheel], lw=1.2, label=self.label(run, 'use'))
                    sliding = run.slip[:, wheel] > 0.5
                    if sliding.any():  # shaded in the run's colour when runs are compared
                        ax.fill_between(run.t, 0, 1, where=sliding, transform=ax.get_xaxis_transform(), alpha=0.2,
                                        color=line.get_color() if self.many else 'tab:red', lw=0,
                                        label=self.label(run, 'sliding'))
            ax.axhline(1.0, color='k', ls='--', lw=1.0, label='limit |f_i| = mu_s N_i')
            ax.set(title=f'{name} wheel', ylabel='friction use')
            ax.set_ylim(bottom=0.0)
            _note_missing(ax, self.runs, legend=False)
        for ax in axes[1]:
            ax.set_xlabel('time (s)')
        entries = {text: handle for ax in axes.flat for handle, text in zip(*ax.get_legend_handles_labels())}
        if any(len(run.loads) and np.isfinite(run.loads).any() for run in self.runs):  # one legend, four wheels
            axes[0, 0].legend(entries.values(), entries.keys(), loc='best', fontsize='small')
        fig.suptitle('Friction use |f_i| / (mu_s N_i) of each wheel' + self.title_suffix)
        self.save(fig, 'friction_use')


def _note_missing(ax, runs: Sequence[RunData], legend: bool = True) -> None:
    """Grid and (``legend``) legend; a note when no run recorded the contact (a bag without wheel_contact)."""
    ax.grid(True, alpha=0.3)
    if any(len(run.loads) and np.isfinite(run.loads).any() for run in runs):
        if legend:
            ax.legend(loc='best', fontsize='small')
    else:
        ax.text(0.5, 0.5, 'no wheel-wall contact recorded', transform=ax.transAxes, ha='center', va='center')
