"""The paper's figures as PNG (matplotlib, Agg backend), for one run or several overlaid.

| file | paper figures |
|---|---|
| path.png | 6, 14, 22: reference vs actual path of the centre |
| position.png | 4, 20: x(t), y(t) against the reference |
| tracking_error.png | 7, 15, 23 (only for runs with a reference) |
| attitude.png | 5, 10, 13, 21: attitude angle theta(t) |
| wheel_tracks.png | 8, 11, 16, 24: tracks of the four wheel axle centres |
| constraint_forces.png | 9, 12, 17, 25: F_X, F_Y and M_Z |
| drive_forces.png | 18, 19, 26, 27: left and right drive (traction) forces, and the lateral force |
| normal_loads.png | (wheel-wall contact) normal load of each wheel; below 0 a wheel lifts off |
| friction_use.png | (wheel-wall contact) friction use of each wheel against the limit 1, its slides shaded (compared runs: a strip each, in its colour) |
| machine.png | (a robot file's motor and adhesion blocks, docs/model.md 13) each side's torque applied within its motor's envelope against the one commanded, the chamber's pressure difference dp and adhesion force F_ad: a panel for each a run has (only for such runs) |
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np

from wallbot_msgs_py import topics
from wallbot_sim.plots.errors import PlotError
from wallbot_sim.rundata import RunData

FIGURES = ('path', 'position', 'tracking_error', 'attitude', 'wheel_tracks', 'constraint_forces', 'drive_forces',
           'normal_loads', 'friction_use', 'machine')
"""Base names of the PNG files written, in this order (tracking_error only when a run has a reference, machine
only when one has a machine series)."""
MACHINE_PANELS = ((('tau_L_applied', 'tau_L_cmd'), 'left side torque (N m)'),
                  (('tau_R_applied', 'tau_R_cmd'), 'right side torque (N m)'),
                  (('dp',), 'chamber pressure difference dp (Pa)'), (('F_ad',), 'adhesion force F_ad (N)'))
"""The machine figure's panels: the series each shows (RunData.machine), its y axis."""
MACHINE_LINES = {'tau_L_applied': ('applied', '-'), 'tau_R_applied': ('applied', '-'),
                 'tau_L_cmd': ('commanded', '--'), 'tau_R_cmd': ('commanded', '--'), 'dp': ('dp', '-'),
                 'F_ad': ('F_ad', '-')}
"""Each machine series' legend entry and line style (a command is held from its time to the next one's)."""

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
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt

    out = _prepare_out(Path(out_dir))
    written = []
    for name, fig in run_figures(plt, runs, half_wheelbase, half_track):
        target = out / f'{name}.png'
        try:
            fig.savefig(target, dpi=110)
        except OSError as error:
            raise PlotError(f'cannot write {target}: {error.strerror}') from None
        finally:
            plt.close(fig)
        written.append(target)
    return written


def has_reference(run: RunData) -> bool:
    """Whether the run followed a reference (a driven or resting run has none: its error is NaN)."""
    return bool(np.isfinite(run.ref_x).any())


def run_figures(plt: Any, runs: Sequence[RunData], half_wheelbase: float | None = None,
                half_track: float | None = None) -> Iterator[tuple[str, Any]]:
    """Each figure of ``runs``, laid out, by its name in FIGURES' order; the tracking error only when a run has
    a reference."""
    if half_wheelbase is None or half_track is None:
        from wallbot_sim.config import load_robot_parameters
        params = load_robot_parameters()
        half_wheelbase = params.half_wheelbase if half_wheelbase is None else half_wheelbase
        half_track = params.half_track if half_track is None else half_track
    figures = _Figures(plt, runs)
    drawn = {'path': figures.path, 'position': figures.position, 'tracking_error': figures.tracking_error,
             'attitude': figures.attitude, 'wheel_tracks': lambda: figures.wheel_tracks(half_wheelbase, half_track),
             'constraint_forces': figures.constraint_forces, 'drive_forces': figures.drive_forces,
             'normal_loads': figures.normal_loads, 'friction_use': figures.friction_use, 'machine': figures.machine}
    for name in FIGURES:
        if ((name == 'tracking_error' and not any(has_reference(run) for run in runs))
                or (name == 'machine' and not any(run.machine for run in runs))):
            continue
        fig = drawn[name]()
        fig.tight_layout()
        yield name, fig


def _legend(ax: Any, **options: Any) -> None:
    """The axes' legend beside it, off the data."""
    ax.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize='small', **options)


class _Figures:
    """The figures of ``runs`` (overlaid when several, each run in a colour of its own), one method each."""

    def __init__(self, plt: Any, runs: Sequence[RunData]) -> None:
        self.plt, self.runs = plt, runs
        self.first, self.many = runs[0], len(runs) > 1
        self.title_suffix = '' if self.many else f' ({runs[0].label})'
        self.referenced = [run for run in runs if has_reference(run)]

    def colour(self, run: RunData) -> str:
        index = next(k for k, known in enumerate(self.runs) if known is run)  # by identity: runs hold arrays
        return f'C{index % 10}'

    def label(self, run: RunData, what: str = '') -> str:
        return f'{run.label}{": " + what if what else ""}' if self.many else (what or run.label)

    def _over_time(self, runs: Sequence[RunData], values: Callable[[RunData], np.ndarray], ylabel: str, title: str,
                   what: str) -> Any:
        """One quantity of ``runs`` (``values`` of each) against time."""
        fig, ax = self.plt.subplots(figsize=(8.5, 4.5))
        for run in runs:
            ax.plot(run.t, values(run), lw=1.3, color=self.colour(run), label=self.label(run, what))
        ax.set(xlabel='time (s)', ylabel=ylabel, title=title + self.title_suffix)
        ax.grid(True, alpha=0.3)
        _legend(ax)
        return fig

    def path(self) -> Any:
        first = self.first
        fig, ax = self.plt.subplots(figsize=(8.0, 6.0))
        if len(first.path_x):
            ax.plot(first.path_x, first.path_y, 'k--', lw=1.2, label='reference path')
        elif has_reference(first):
            ax.plot(first.ref_x, first.ref_y, 'k--', lw=1.2, label='reference path')
        for run in self.runs:
            ax.plot(run.x, run.y, lw=1.4, color=self.colour(run), label=self.label(run, 'actual path'))
        ax.plot(first.x[:1], first.y[:1], 'o', color='tab:green', label='start')
        title = 'Path of the centre: reference vs actual' if self.referenced else 'Path of the centre'
        ax.set(xlabel='x (m)', ylabel='y (m)', title=title + self.title_suffix)
        ax.set_aspect('equal', adjustable='datalim')
        ax.grid(True, alpha=0.3)
        _legend(ax)
        return fig

    def position(self) -> Any:
        fig, axes = self.plt.subplots(2, 1, sharex=True, figsize=(8.5, 6.0))
        for ax, coord, refc, name in ((axes[0], 'x', 'ref_x', 'x'), (axes[1], 'y', 'ref_y', 'y')):
            if self.referenced:
                reference = self.referenced[0]
                ax.plot(reference.t, getattr(reference, refc), 'k--', lw=1.2, label=f'reference {name}_d(t)')
            for run in self.runs:
                ax.plot(run.t, getattr(run, coord), lw=1.3, color=self.colour(run),
                        label=self.label(run, f'actual {name}(t)'))
            ax.set(ylabel=f'{name} (m)')
            ax.grid(True, alpha=0.3)
            _legend(ax)
        title = 'Position of the centre against the reference' if self.referenced else 'Position of the centre'
        axes[0].set_title(title + self.title_suffix)
        axes[1].set_xlabel('time (s)')
        return fig

    def tracking_error(self) -> Any:
        return self._over_time(self.referenced, lambda run: run.err, 'tracking error |p - p_d| (m)',
                               'Tracking error', 'tracking error')

    def attitude(self) -> Any:
        return self._over_time(self.runs, lambda run: np.unwrap(run.theta), 'attitude angle theta (rad)',
                               'Attitude angle', 'attitude angle theta')

    def wheel_tracks(self, half_wheelbase: float, half_track: float) -> Any:
        """Each wheel a line style; several runs: each run a colour, the legend naming runs and wheels apart."""
        fig, ax = self.plt.subplots(figsize=(8.0, 6.0))
        styles = ('-', '--', '-.', ':')
        for run in self.runs:
            for style, (name, (wx, wy)) in zip(styles, wheel_tracks(run, half_wheelbase, half_track).items()):
                pretty = name.replace('wheel_', '').replace('_', ' ')
                ax.plot(wx, wy, style, lw=1.0, color=self.colour(run) if self.many else None,
                        label=None if self.many else f'{pretty} wheel')
        if self.many:
            for style, name in zip(styles, topics.WHEEL_JOINTS):
                ax.plot([], [], style, color='k', lw=1.0, label=name.replace('wheel_', '').replace('_', ' ') + ' wheel')
            for run in self.runs:
                ax.plot([], [], '-', color=self.colour(run), lw=2.0, label=run.label)
        ax.set(xlabel='x (m)', ylabel='y (m)', title='Tracks of the four wheels' + self.title_suffix)
        ax.set_aspect('equal', adjustable='datalim')
        ax.grid(True, alpha=0.3)
        _legend(ax)
        return fig

    def constraint_forces(self) -> Any:
        fig, axes = self.plt.subplots(2, 1, sharex=True, figsize=(8.5, 6.0))
        for run in self.runs:
            colour = self.colour(run) if self.many else None
            axes[0].plot(run.t, run.Fx, '-', lw=1.2, color=colour, label=self.label(run, 'F_X'))
            axes[0].plot(run.t, run.Fy, '--', lw=1.2, color=colour, label=self.label(run, 'F_Y'))
            axes[1].plot(run.t, run.Mz, lw=1.2, color=self.colour(run), label=self.label(run, 'M_Z'))
        axes[0].set(ylabel='constraint force (N)',
                    title='Constraint forces and torque on the chassis' + self.title_suffix)
        axes[1].set(xlabel='time (s)', ylabel='constraint torque M_Z (N m)')
        for ax in axes:
            ax.grid(True, alpha=0.3)
            _legend(ax)
        return fig

    def drive_forces(self) -> Any:
        fig, axes = self.plt.subplots(3, 1, sharex=True, figsize=(8.5, 7.5))
        for run in self.runs:
            axes[0].plot(run.t, run.F_left, lw=1.2, color=self.colour(run), label=self.label(run, 'left drive force F_L'))
            axes[1].plot(run.t, run.F_right, lw=1.2, color=self.colour(run),
                         label=self.label(run, 'right drive force F_R'))
            axes[2].plot(run.t, run.F_lateral, lw=1.2, color=self.colour(run), label=self.label(run, 'lateral force F_lat'))
        axes[0].set(ylabel='F_L (N)', title='Drive forces' + self.title_suffix)
        axes[1].set(ylabel='F_R (N)')
        axes[2].set(xlabel='time (s)', ylabel='F_lat (N)')
        for ax in axes:
            ax.grid(True, alpha=0.3)
            _legend(ax)
        return fig

    def normal_loads(self) -> Any:
        fig, ax = self.plt.subplots(figsize=(8.5, 4.5))
        styles = ('-', '--', '-.', ':')
        for run in self.runs:
            if len(run.loads):
                for i, (style, name) in enumerate(zip(styles, topics.WHEEL_JOINTS)):
                    ax.plot(run.t, run.loads[:, i], style if self.many else '-', lw=1.2,
                            color=self.colour(run) if self.many else None,
                            label=self.label(run, name.replace('wheel_', '').replace('_', ' ')))
        ax.axhline(0.0, color='k', lw=0.8)
        ax.set(xlabel='time (s)', ylabel='normal load N_i (N)',
               title='Normal loads of the wheels (below 0: lifts off)' + self.title_suffix)
        _note_missing(ax, self.runs)
        return fig

    def friction_use(self) -> Any:
        """A panel a wheel, laid out as on the robot. One run: its slides shaded; several: each run's slides a
        strip of its colour along the panel's foot."""
        fig, axes = self.plt.subplots(2, 2, sharex=True, sharey=True, figsize=(10.5, 6.5))
        strip = 0.05
        for wheel, ax in zip(range(4), (axes[0, 0], axes[1, 0], axes[0, 1], axes[1, 1])):  # front row, left column
            name = topics.WHEEL_JOINTS[wheel].replace('wheel_', '').replace('_', ' ')
            for k, run in enumerate(self.runs):
                if not len(run.use):
                    continue
                ax.plot(run.t, run.use[:, wheel], lw=1.2, color=self.colour(run), label=self.label(run, 'use'))
                sliding = run.slip[:, wheel] > 0.5
                if sliding.any():
                    low, high = (k * strip, (k + 0.8) * strip) if self.many else (0.0, 1.0)
                    ax.fill_between(run.t, low, high, where=sliding, transform=ax.get_xaxis_transform(),
                                    alpha=0.6 if self.many else 0.2, color=self.colour(run) if self.many else 'tab:red',
                                    lw=0, label=self.label(run, 'sliding'))
            ax.axhline(1.0, color='k', ls='--', lw=1.0, label='limit |f_i| = mu_s N_i')
            ax.set(title=f'{name} wheel', ylabel='friction use (-)')
            ax.set_ylim(bottom=-len(self.runs) * strip * 1.2 if self.many else 0.0, top=1.15)
            _note_missing(ax, self.runs, legend=False)
        for ax in axes[1]:
            ax.set_xlabel('time (s)')
        entries = {text: handle for ax in axes.flat for handle, text in zip(*ax.get_legend_handles_labels())}
        if any(len(run.loads) and np.isfinite(run.loads).any() for run in self.runs):  # one legend, four wheels
            _legend(axes[0, 1], handles=list(entries.values()), labels=list(entries.keys()))
        fig.suptitle('Friction use |f_i| / (mu_s N_i) of each wheel' + self.title_suffix)
        return fig

    def machine(self) -> Any:
        """A panel for each of MACHINE_PANELS some run has: applied and commanded a line style, each run a colour."""
        panels = [(names, ylabel) for names, ylabel in MACHINE_PANELS
                  if any(name in run.machine for run in self.runs for name in names)]
        fig, axes = self.plt.subplots(len(panels), 1, sharex=True, figsize=(8.5, 2.6 * len(panels) + 1.0),
                                      squeeze=False)
        for ax, (names, ylabel) in zip(axes[:, 0], panels):
            for run in self.runs:
                for name in names:
                    if name in run.machine:
                        t, values = run.machine[name]
                        what, style = MACHINE_LINES[name]
                        ax.plot(t, values, style, lw=1.2, color=self.colour(run), label=self.label(run, what),
                                drawstyle='steps-post' if name.endswith('_cmd') else 'default')
            ax.set(ylabel=ylabel)
            ax.grid(True, alpha=0.3)
            _legend(ax)
        axes[-1, 0].set_xlabel('time (s)')
        axes[0, 0].set_title('The machine: motors and vacuum chamber' + self.title_suffix)
        return fig


def _note_missing(ax: Any, runs: Sequence[RunData], legend: bool = True) -> None:
    """Grid and (``legend``) legend; a note when no run recorded the contact (a bag without wheel_contact)."""
    ax.grid(True, alpha=0.3)
    if any(len(run.loads) and np.isfinite(run.loads).any() for run in runs):
        if legend:
            _legend(ax)
    else:
        ax.text(0.5, 0.5, 'no wheel-wall contact recorded', transform=ax.transAxes, ha='center', va='center')
