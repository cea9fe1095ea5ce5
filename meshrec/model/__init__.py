"""Models: cleaned meshes, curvature tables, surface queries, the cache, libraries."""
