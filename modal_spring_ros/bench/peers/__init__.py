"""
The project against a peer engine on the same scene.

``newton_peer`` steps a scene with Newton's semi-implicit solver (optional); ``peer`` compares
the two at equal error.
"""
