"""
The simulation thread and everything about the stream it makes.

``simulation_thread`` steps, applies requests between steps (each by its handler in
``request_handling``) and hands each frame to its ``Outputs``; ``outputs`` publishes them (clouds,
markers, the clock, TF, diagnostics, the capture); ``stream_settings`` is what the thread reads
every frame; ``run_pace`` and ``stream_time`` say which simulation time is owed and published;
``publication_mode`` keeps the middleware out of the stepping thread's way; ``stream_book`` counts
the thread's windows, frames and divergences for ``diagnostics``, which turns them into a message;
``divergence_streak`` holds a run that keeps diverging; ``plan_watch`` watches an automatic plan in
the thread's idle time. Something the thread does every frame goes here.
"""
