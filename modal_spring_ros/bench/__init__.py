"""
Benchmarks: what the project costs and how accurate it is, as suites with results on disk.

``charts`` draws them. The rooms:

* ``accuracy``: speed against accuracy (``tradeoff``, its report and ``analysis``, ``failure``
  where the method fails), the automatic plan's promise (``promise``, ``auto_scenes``), the
  README's figures (``headline``), the filter's response (``response``).
* ``costs``: what a step, a frame, a stream, memory and a mesh cost (``steps``, ``stream``
  with ``busy_load`` and ``process_cpu``, ``memory`` (the scale suite), ``meshes``).
* ``peers``: the project against another engine on the same scene (``peer``, ``newton_peer``).

A new suite is a module in its room with a ``run`` and its outputs, named in
``cli/modal_spring_bench.py``.
"""
