"""
The node's first frames on a large scene: streaming while its spring sample is trained.

``modal.forces`` ``sampled`` trains a sample of the springs before the run can use it: a run of
the scene with every spring for snapshots, then the fit (about 3 s on ``sheet_100x100``, and
over a minute of CPU on ``sheet_316x316``, beside the modes). A node that waited for it would
show nothing meanwhile. On scenes of :data:`STAGED_SPRINGS` springs and more the node starts
instead with the springs refreshed every few steps (``modal.forces`` ``refreshed``: every spring
evaluated every ``modal.force_refresh`` steps, their tangent between, accurate in small
deformation), and asks its change preparer for the sampled forces as its first change: the
sample is trained in the worker process while the stream runs, ``/diagnostics`` says
``preparing modal.forces='sampled'`` meanwhile, and the run takes the sample, its state carried
over, once it is ready (at once where the sample cache has it). ``modal.forces`` reads
``sampled`` throughout: what was asked for, and what the run settles on; should the training
fail, the parameter goes back to ``refreshed`` with the reason in the log, as a failed change
does.
"""
from __future__ import annotations

from typing import Any

from modal_spring_ros.core.config import SAMPLE_MIN_SPRINGS, SimulationConfig
from modal_spring_ros.core.model.scene import Scene

#: scenes with this many springs or more start before their sample is trained (the size from
#: which the automatic choice samples springs, and training takes seconds)
STAGED_SPRINGS = SAMPLE_MIN_SPRINGS
#: the forces the first frames are stepped with while the sample trains
FIRST_FORCES = 'refreshed'


def first_values(config: SimulationConfig, scene: Scene) -> dict[str, Any]:
    """
    Return the parameters the first run takes in place of the values asked for (or none).

    Only a modal run asked for sampled springs (not the automatic plan, which measures the
    forces it chooses) on a scene of :data:`STAGED_SPRINGS` springs or more.
    """
    if (config.method != 'modal' or config.auto or config.forces != 'sampled'
            or scene.n_springs < STAGED_SPRINGS):
        return {}
    return {'modal.forces': FIRST_FORCES}
