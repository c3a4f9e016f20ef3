"""
Pictures of a run: the sheet as RViz shows it, as an animated GIF or a strip of snapshots.

The view looks at a 2D scene's own plane, or from -y at the x-z plane of a 3D one (z up, as in a
z-up world). Each particle is coloured by its displacement from rest (the cloud's
``displacement`` field), the surface's triangles are filled when the scene has them, and the
clamp's particles are drawn in black. Limits and colours are fixed over the whole picture, so
frames compare. matplotlib draws off screen (no display, no pyplot state).
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from modal_spring_ros.runs.comparison import RunData
import numpy as np

#: what each picture format is, by file suffix
FORMATS = {'.gif': 'an animation', '.png': 'a strip of snapshots'}
SIDE_VIEW = (0, 2)  # x across, z up


def view_axes(run: RunData) -> tuple[int, int]:
    """Return the world axes drawn across and up: a 2D scene's plane, else x and z."""
    if run.scene is not None and run.scene.dimension == 2:
        return tuple(run.scene.axes)
    return SIDE_VIEW


def frame_indices(t: np.ndarray, fps: float, start: float, duration: float | None
                  ) -> np.ndarray:
    """Return the frames nearest to ``fps`` pictures a second from ``start`` for ``duration``."""
    end = t[-1] if duration is None else min(t[-1], start + duration)
    if not t.size or start > t[-1] or end < start:
        raise ValueError(f'no frame between {start:g} s and {end:g} s '
                         f'(the run has {t.size} frames, {t[0] if t.size else 0:g} s to '
                         f'{t[-1] if t.size else 0:g} s)')
    wanted = np.arange(start, end + 1e-9, 1.0 / fps)
    picked = np.clip(np.searchsorted(t, wanted), 0, t.size - 1)
    return np.unique(picked)


def render(run: RunData, path: str | Path, *, fps: float = 20.0, start: float = 0.0,
           duration: float | None = None, snapshots: int = 6, dpi: int = 80,
           progress: Callable[[int, int], None] | None = None) -> int:
    """
    Draw ``run`` into ``path`` (``.gif``: an animation at ``fps``; ``.png``: ``snapshots``).

    Returns how many frames were drawn; ``progress(done, total)`` is called as they are.

    :raises ValueError: an unknown picture format, or no frame in the time asked for.
    """
    # deferred on purpose: matplotlib takes ~0.5 s to import and only pictures need it
    from matplotlib.animation import FuncAnimation, PillowWriter
    from matplotlib.figure import Figure
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise ValueError(f"{path}: cannot tell the picture's format from its name (use "
                         f"{' or '.join(f'{s} for {w}' for s, w in FORMATS.items())})")
    picked = frame_indices(run.t, fps, start, duration)
    if path.suffix.lower() == '.png':
        picked = picked[np.linspace(0, picked.size - 1, min(snapshots, picked.size)).astype(int)]
    drawing = _Drawing(run, picked)
    if path.suffix.lower() == '.png':
        fig = Figure(figsize=(2.2 * picked.size, 3.0))
        for k, (ax, frame) in enumerate(zip(np.atleast_1d(fig.subplots(1, picked.size)),
                                            picked)):
            drawing.draw(ax, frame)
            if progress:
                progress(k + 1, picked.size)
        fig.tight_layout()
        fig.savefig(path, dpi=dpi)
        return picked.size
    fig = Figure(figsize=(4.5, 4.5))
    ax = fig.add_subplot()
    drawing.draw(ax, picked[0])
    fig.tight_layout()  # room for the labels, kept for every frame

    def update(k: int):
        ax.clear()
        drawing.draw(ax, picked[k])
        if progress:
            progress(k + 1, picked.size)
        return []
    FuncAnimation(fig, update, frames=picked.size, blit=False).save(
        path, writer=PillowWriter(fps=fps), dpi=dpi)
    return picked.size


class _Drawing:
    """What every frame of one picture shares: the view, limits, colour scale, triangles."""

    def __init__(self, run: RunData, frames: np.ndarray):
        self.run = run
        self.across, self.up = view_axes(run)
        shown = run.positions[frames]
        self.displacement = np.linalg.norm(shown - run.rest[None], axis=2)
        self.top = max(float(self.displacement.max()), 1e-12)
        self.frames = {int(f): k for k, f in enumerate(frames)}
        low = shown[..., [self.across, self.up]].min(axis=(0, 1))
        high = shown[..., [self.across, self.up]].max(axis=(0, 1))
        margin = 0.05 * max(float((high - low).max()), 1e-6)
        self.limits = low - margin, high + margin
        scene = run.scene
        self.triangles = scene.surface_triangles() if scene is not None else np.empty((0, 3))
        self.fixed = scene.fixed if scene is not None else np.zeros(shown.shape[1], bool)

    def draw(self, ax, frame: int) -> None:
        x = self.run.positions[frame][:, [self.across, self.up]]
        value = self.displacement[self.frames[int(frame)]]
        if len(self.triangles):
            ax.tripcolor(x[:, 0], x[:, 1], self.triangles, value, shading='gouraud',
                         cmap='viridis', vmin=0.0, vmax=self.top, alpha=0.8)
        ax.scatter(x[~self.fixed, 0], x[~self.fixed, 1], c=value[~self.fixed], s=6,
                   cmap='viridis', vmin=0.0, vmax=self.top)
        ax.scatter(x[self.fixed, 0], x[self.fixed, 1], c='black', s=10)
        ax.set_xlim(self.limits[0][0], self.limits[1][0])
        ax.set_ylim(self.limits[0][1], self.limits[1][1])
        ax.set_aspect('equal')
        ax.set_xlabel(f"{'xyz'[self.across]} (m)")
        ax.set_ylabel(f"{'xyz'[self.up]} (m)")
        ax.set_title(f't = {self.run.t[frame]:.2f} s', fontsize=9)
