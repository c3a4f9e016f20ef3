"""
An automatic plan watched while it runs: its error measured again from the run's own state.

The watch (:mod:`.run_watch`) over windows of shadow runs (:mod:`.shadows`) against what the
pilot measured (:mod:`.windows`), and a twin moved by a hair that says whether the motion
amplifies its differences (:mod:`.amplification`), which alone watches a full run
(:mod:`.twin_watch`).
"""
