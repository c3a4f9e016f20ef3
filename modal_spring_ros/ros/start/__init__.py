"""
How the node starts: what streams first, and what it says while it prepares.

``start_up`` chooses the first values a large scene streams with (fewer modes, refreshed
springs) before the parameters asked for are prepared; ``start_up_report`` publishes what is
being prepared on ``/diagnostics`` before the first frame. Something the node does once, before
the stream, belongs here; what runs while it streams is ``stream``'s.
"""
