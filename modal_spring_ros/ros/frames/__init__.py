"""
TF, heard and broadcast.

The tree the node hears (``frame_tree``: named frames and the rigid transforms between them)
and the frames it broadcasts (``tf``). Inputs carry their messages into the node's frame
through it; outputs broadcast the object's and the clamp's frames.
"""
