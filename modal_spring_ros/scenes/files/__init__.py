"""
Scenes as files: read within bounds, written, archived.

``yaml_reading`` reads a scene's YAML so that no file can hang or exhaust the loader;
``writing`` writes a Scene in the scene file format; ``scene_archive`` keeps a scene as an
archive of its arrays (what bags and runs keep); ``declared_size`` counts a file's particles
without building the scene; ``npz_headers`` reads what an ``.npz``'s arrays declare before any
is read (every ``.npz`` the project reads). A new way to keep a scene goes here.
"""
