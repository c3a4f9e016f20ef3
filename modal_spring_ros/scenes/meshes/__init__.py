"""
Mesh files made mass-spring networks.

``mesh_files`` reads surfaces (OBJ, STL, PLY, glTF/GLB, with trimesh) and tetrahedra (Gmsh,
VTK, with meshio), every file checked first; ``mesh_network`` makes particles, springs, masses
and stiffness of a mesh from a material (filling a closed surface); ``inside`` tells which
points a closed surface encloses. A new mesh format is a reader in ``mesh_files``.
"""
