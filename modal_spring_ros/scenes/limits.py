"""
The bounds a scene must stay within.

Ranges of its physical values, the length of its suggested run, and the memory it may take on this
machine.
"""
from __future__ import annotations

import os

#: Ranges of the physical values: far beyond any scene, and small enough that no sum, square
#: or product of them in the engine overflows.
LIMITS = {'position': 1e6, 'mass': 1e9, 'stiffness': 1e12, 'gravity': 1e4, 'amplitude': 1e3,
          'amplitude_deg': 1e4, 'frequency_hz': 1e5, 'phase': 1e6, 'ramp_s': 1e6,
          'damping.ratio': 100.0, 'damping.alpha': 1e6, 'damping.beta': 1e3, 'duration': 1e7,
          'dt': 10.0}
#: Most steps a scene's suggested run may take (its duration over its step).
MAX_STEPS = 10**9
#: Memory a scene takes to build, compute its modes (sparse LU) and run, per particle, bytes:
#: measured on sheet_316x316 (99,856 particles, 1.15 GB at the peak of its factorisation).
BYTES_PER_PARTICLE = 12_000


def available_memory() -> int:
    """Memory this machine has available now, bytes (MemAvailable; all of it elsewhere)."""
    try:
        with open('/proc/meminfo') as fh:
            for line in fh:
                if line.startswith('MemAvailable:'):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES')
