"""
The bounds a scene must stay within.

Ranges of its physical values, the length of its suggested run, and the memory it may take on this
machine.
"""
from __future__ import annotations

import os
import resource

#: Ranges of the physical values: far beyond any scene, and small enough that no sum, square
#: or product of them in the engine overflows.
LIMITS = {'position': 1e6, 'mass': 1e9, 'stiffness': 1e12, 'gravity': 1e4, 'amplitude': 1e3,
          'amplitude_deg': 1e4, 'frequency_hz': 1e5, 'phase': 1e6, 'ramp_s': 1e6,
          'damping.ratio': 100.0, 'damping.alpha': 1e6, 'damping.beta': 1e3, 'duration': 1e7,
          'dt': 10.0}
#: Most steps a scene's suggested run may take (its duration over its step).
MAX_STEPS = 10**9
#: The least memory a particle takes in any run, bytes (its share of the model and of the sparse
#: factor of a sheet): a scene beyond what the machine has at this rate is refused before it is
#: built. A run's own estimate, by stage and options, is checked before it starts
#: (:mod:`modal_spring_ros.core.memory_estimate`).
BYTES_PER_PARTICLE = 4_000


def available_memory() -> int:
    """
    Return the memory this process may still take, bytes.

    The system's available memory (``MemAvailable``; all of it elsewhere), or less under an
    address-space limit (``ulimit -v``) less what this process maps already.
    """
    have = None
    try:
        with open('/proc/meminfo') as fh:
            for line in fh:
                if line.startswith('MemAvailable:'):
                    have = int(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    if have is None:
        have = os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES')
    limit = resource.getrlimit(resource.RLIMIT_AS)[0]
    if limit != resource.RLIM_INFINITY:
        have = min(have, max(limit - mapped_bytes(), 0))
    return have


def mapped_bytes() -> int:
    """Return the address space this process maps now, bytes (0 where it cannot be read)."""
    try:
        with open('/proc/self/statm') as fh:
            return int(fh.read().split()[0]) * os.sysconf('SC_PAGE_SIZE')
    except OSError:
        return 0
