"""
modal_spring_ros: stream physically based, frequency-filtered mass-spring deformations.

The numerical core (scene, forces, stiffness, modes, integrators, filter, simulation) has no
ROS dependency; the ROS node, recorder and player are thin layers over it.

The Python API's common names are here (``from modal_spring_ros import load_scene,
SimulationConfig, build_simulation, FilterBand``), each imported from its own module on first
use: ``import modal_spring_ros`` loads nothing else, so a console script's imports stay under
its Ctrl-C guard (``cli/launcher.py``) and a layer that imports one of its modules loads no
other.
"""
import importlib

__version__ = '0.1.0'

#: the façade: name -> the module that defines it
API = {
    'build_simulation': 'modal_spring_ros.core.factory',
    'builtin_scene_names': 'modal_spring_ros.scenes.resources',
    'FilterBand': 'modal_spring_ros.core.filter_band',
    'load_scene': 'modal_spring_ros.scenes.resources',
    'Pose': 'modal_spring_ros.core.model.colliders',
    'Load': 'modal_spring_ros.core.loads.base',
    'record': 'modal_spring_ros.runs.run',
    'Scene': 'modal_spring_ros.core.model.scene',
    'scene_from_yaml': 'modal_spring_ros.scenes.schema',
    'SimulationConfig': 'modal_spring_ros.core.config',
}
__all__ = sorted(API) + ['__version__']


def __getattr__(name: str):
    """Import a façade name from its module on first use (PEP 562)."""
    if name not in API:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(API[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(API))
