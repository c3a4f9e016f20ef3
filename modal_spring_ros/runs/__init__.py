"""
Recorded runs as arrays: ``.npz`` files of headless runs, and comparing two runs.

Imports only from ``core`` and ``scenes``.
"""
