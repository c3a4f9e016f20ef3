"""
The spring-sample cache on disk: one ``.npz`` a sample, in the user's cache folder.

The core trains spring samples and validates what it is given back
(:mod:`modal_spring_ros.core.forces.samples`); keeping them between runs is this module's: the
folder is ``$MODAL_SPRING_ROS_CACHE`` (empty: no cache), else ``$XDG_CACHE_HOME`` or
``~/.cache``, under ``modal_spring_ros/samples``. An entry is written to a temporary name and
renamed into place, so a reader never sees half of one; an unreadable entry is refused (the core
then discards it and trains again), and a folder that cannot be written only costs training
again.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping
import zipfile

from modal_spring_ros.core.forces.samples import CacheEntryError
from modal_spring_ros.scenes.files.npz_headers import declared_arrays
import numpy as np

#: environment variable naming the cache folder ("" disables the cache)
CACHE_ENV = 'MODAL_SPRING_ROS_CACHE'


def cache_folder() -> Path | None:
    """Where samples are kept: ``$MODAL_SPRING_ROS_CACHE``, else the user's cache folder."""
    value = os.environ.get(CACHE_ENV)
    if value == '':
        return None
    if value:
        return Path(value)
    base = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return Path(base) / 'modal_spring_ros' / 'samples'


class SampleCache:
    """A :class:`~modal_spring_ros.core.forces.base.SampleStore` of ``.npz`` files."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)

    def path(self, key: str) -> Path:
        return self.folder / f'{key}.npz'

    def where(self, key: str) -> str:
        return str(self.path(key))

    def load(self, key: str) -> Mapping[str, np.ndarray] | None:
        path = self.path(key)
        if not path.is_file():
            return None
        try:
            declared_arrays(path)           # headers first: a damaged one is never allocated
            with np.load(path, allow_pickle=False) as data:
                return {name: np.asarray(data[name]) for name in data.files}
        except (OSError, KeyError, ValueError, TypeError, EOFError,
                zipfile.BadZipFile) as exc:
            raise CacheEntryError(f'unreadable ({type(exc).__name__}: {exc})') from None

    def save(self, key: str, arrays: Mapping[str, np.ndarray]) -> None:
        path = self.path(key)
        tmp = path.with_suffix('.tmp.npz')
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            np.savez(tmp, **arrays)
            os.replace(tmp, path)
        except OSError:
            try:  # a full disk leaves no half-written entry behind
                tmp.unlink()
            except OSError:
                pass

    def discard(self, key: str) -> None:
        try:
            self.path(key).unlink()
        except OSError:
            pass


def sample_cache() -> SampleCache | None:
    """Return the cache the environment names (None: ``$MODAL_SPRING_ROS_CACHE`` is empty)."""
    folder = cache_folder()
    return SampleCache(folder) if folder is not None else None
