"""
The coordinates a modal run steps: rest modes, their derivatives, and how many to keep.

The rest modes (computed as far as a band needs them), the modal derivatives and static load
vectors they add, the choice between the two bases, and the automatic choice of modes.
"""
