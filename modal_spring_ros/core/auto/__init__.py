"""
``modal.auto``'s measurement: a pilot run against the truth, its measured error, its cost.

The prediction chooses (:mod:`~modal_spring_ros.core.bases.mode_selection`); this room checks
the plan on the run itself and prices it (the work model).
"""
