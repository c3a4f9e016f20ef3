"""
Bags as folders: written, read, reindexed, and what a run keeps in them.

``writer`` and ``reader`` are rosbag2's MCAP storage (``reindex`` repairs a killed one);
``capture`` records a run losslessly, ``run_loading``, ``sim_time`` and ``applied_changes``
read one back; ``reference_bags`` are the bags the tests re-simulate. A new way to keep or read
a bag goes here.
"""
