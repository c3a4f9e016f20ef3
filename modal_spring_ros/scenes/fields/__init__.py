"""
A scene file's fields, each read into what the scene needs, every refusal naming the field.

``reader`` (typed reading of a field), ``limits`` (the bounds a scene must stay within, and the
memory available), ``fixed_regions`` (which particles the clamp holds), ``mesh_fields`` (a mesh
scene's mesh and material), ``bending_fields`` (a listed scene's bending, hinge by hinge). A new
field is one module here, read by ``scenes/schema.py``.
"""
